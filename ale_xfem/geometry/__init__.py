"""Shapes and exact polygon geometry (areas, centroids, clipping), below any physics."""
