"""ale_xfem: multi-material ALE with enriched mixed cells on FEniCSx (Folzan, Le Tallec & Perlat 2011)."""

__version__ = "0.1.0"
