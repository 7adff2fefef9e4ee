"""Datasets on disk: the versioned format, generation, the scores file, validation, imports."""

__all__: list[str] = []
