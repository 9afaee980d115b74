"""Frozen condition encoders (text; image) shared by the shape prior and the transformer."""
