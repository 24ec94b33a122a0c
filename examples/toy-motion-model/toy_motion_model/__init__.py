"""A lab's own motion model as a motion-study plugin (see docs/adding-a-model.md)."""
