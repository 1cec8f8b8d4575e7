"""Run outputs: summary.json, profile.csv / cells.csv, the VTK series, plots."""
