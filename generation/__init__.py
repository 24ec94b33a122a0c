"""Motion data, models, training, sampling and rendering (no web, no queue)."""
