"""The transport phase: material-by-material remaps onto the regularised mesh, 1D and 2D."""
