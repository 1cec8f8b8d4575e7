"""Run outputs: summary.json, profile.csv / cells.csv, VTX, plots."""
