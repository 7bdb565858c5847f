"""What the two passes compare: per-frame features of each take and the local-cost metrics (kernels apart)."""
