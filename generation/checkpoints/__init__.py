"""Checkpoints: the file store, writing and reading a checkpoint with its header, the checks
of a checkpoint against its data, and the build budget of a model's training."""
