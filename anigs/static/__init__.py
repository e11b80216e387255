"""The static canonical 3DGS fit and its densification strategy."""
