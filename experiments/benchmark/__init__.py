"""The real-data benchmark (``wander benchmark ...``): protocol, model, figures, datasets."""
