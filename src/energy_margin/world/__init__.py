"""The world: engine-agnostic scenes, frame states and the geometry of object sets."""

__all__: list[str] = []
