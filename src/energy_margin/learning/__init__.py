"""Learned energy margins: frame features and a small regressor fitted to analysed scores."""

__all__: list[str] = []
