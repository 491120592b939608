"""What a run is compared with and shown as: ground truth, plots, animation."""
