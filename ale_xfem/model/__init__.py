"""The data model: mesh arrays and cell geometry, materials and state, boundaries, the
mixed cells and the interface geometry (PLIC).  It imports no stepper, remap or output."""
