"""The software a result depends on: the physics engine and the versions of MuJoCo and numpy.

Frames and scores depend on the engine's version (between MuJoCo 4.0.0 and 4.0.1 the generated
frames of one seed move by centimetres and the same frames score up to 0.13 apart), so every file
that holds results records :func:`engine_versions` under the key :data:`VERSIONS_KEY`:
``dataset.json``, ``analysis.json`` and every run's settings file. :func:`engine_difference`
compares two such records.
"""

from __future__ import annotations

from typing import Any

#: The key of the record in ``dataset.json``, ``analysis.json`` and every run's settings file.
VERSIONS_KEY = "versions"
#: How each recorded library is named in messages.
DISPLAY_NAMES = {
    "mujoco": "MuJoCo",
    "pybullet": "PyBullet",
    "numpy": "numpy",
    "mujoco-warp": "MuJoCo Warp",
    "warp-lang": "Warp",
}
#: Written for PyBullet when the engine is PyBullet but it is not installed.
NOT_INSTALLED = "not installed"


def engine_versions(engine: str = "mujoco") -> dict[str, str]:
    """The engine and the versions of the libraries its results depend on.

    MuJoCo is always recorded (every task's scene is a MuJoCo model, whatever engine rolls it
    out), numpy too, PyBullet when it is the engine, and MuJoCo Warp and Warp for ``"mujoco-warp"``.

    Args:
        engine: the physics engine, ``"mujoco"``, ``"pybullet"`` or ``"mujoco-warp"``.

    Returns:
        ``{"engine": engine, "mujoco": "4.0.0", "numpy": "2.4.6"}``, plus ``"pybullet"`` when
        ``engine`` is ``"pybullet"``, ``"mujoco-warp"`` and ``"warp-lang"`` when it is
        ``"mujoco-warp"`` (each a version, or ``"not installed"``).
    """
    import mujoco
    import numpy

    versions = {"engine": str(engine), "mujoco": str(mujoco.__version__), "numpy": str(numpy.__version__)}
    from importlib.metadata import PackageNotFoundError, version

    for package in _ENGINE_PACKAGES.get(engine, ()):
        try:
            versions[package] = version(package)
        except PackageNotFoundError:
            versions[package] = NOT_INSTALLED
    return versions


#: The packages besides MuJoCo whose versions decide an engine's results.
_ENGINE_PACKAGES = {"pybullet": ("pybullet",), "mujoco-warp": ("mujoco-warp", "warp-lang")}


def recorded_versions(document: Any) -> dict[str, str] | None:
    """The versions record of a parsed JSON document, ``None`` when it has none (or not a valid one).

    A file written before the record existed, or one whose record is not an object of strings,
    gives ``None``: its versions are unknown.
    """
    if not isinstance(document, dict):
        return None
    record = document.get(VERSIONS_KEY)
    if not isinstance(record, dict) or not all(isinstance(value, str) for value in record.values()):
        return None
    return {str(key): value for key, value in record.items()}


def engine_difference(recorded: dict[str, str], current: dict[str, str]) -> tuple[str, str, str] | None:
    """The first engine whose version differs between two records, or ``None``.

    MuJoCo is compared, then PyBullet when either record's engine is PyBullet; a library that
    one of the records lacks is not compared. numpy is not compared (it moves no frame).

    Returns:
        ``(name, recorded version, current version)``, e.g. ``("MuJoCo", "3.3.0", "4.0.0")``.
    """
    libraries = ["mujoco"]
    for engine, packages in _ENGINE_PACKAGES.items():
        if engine in (recorded.get("engine"), current.get("engine")):
            libraries.extend(packages)
    for library in libraries:
        before, now = recorded.get(library), current.get(library)
        if before is not None and now is not None and before != now:
            return DISPLAY_NAMES[library], before, now
    return None


__all__ = ["VERSIONS_KEY", "engine_difference", "engine_versions", "recorded_versions"]
