"""A demonstration's model: asset paths of a robosuite XML re-rooted here, and the XML compiled.

A path that does not exist is re-rooted under the ``assets`` folder given (the part after
``models/assets/``, else the file's name) or under the installed robosuite's ``models/assets``
folder (found without importing robosuite).
"""

from __future__ import annotations

import importlib.util
import xml.etree.ElementTree as ElementTree
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco

from energy_margin.data.robomimic_hdf5 import (
    _one_line,
    _RawDemo,
)
from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.tasks.scene_model import model_hash

__all__ = ["compile_xml", "reroot_assets"]


#: Elements of a model whose ``file`` attributes name asset files, and the compiler folder each reads.
_ASSET_ELEMENTS = {"mesh": "meshdir", "skin": "meshdir", "hfield": "assetdir", "texture": "texturedir"}
#: The six face files of a cube texture.
_TEXTURE_FACES = ("fileright", "fileleft", "fileup", "filedown", "filefront", "fileback")
_ROBOSUITE_ASSETS = "robosuite/models/assets/"
_MODELS_ASSETS = "models/assets/"


@dataclass(frozen=True)
class _BuiltModel:
    """A demonstration's model: the re-rooted XML, the compiled model and its SHA-256."""

    xml: str
    model: mujoco.MjModel
    sha256: str


def _assets_folder(assets: Path | str | None) -> Path | None:
    if assets is None:
        return None
    folder = Path(assets)
    if not folder.is_dir():
        raise InvalidParameterError("assets", f"must be a folder, got {str(folder)!r}")
    return folder.resolve()


def _robosuite_assets() -> Path | None:
    """The installed robosuite's ``models/assets`` folder, found without importing robosuite."""
    try:
        spec = importlib.util.find_spec("robosuite")
    except (ImportError, ValueError):
        return None
    for location in (spec.submodule_search_locations or []) if spec is not None else []:
        folder = Path(location) / "models" / "assets"
        if folder.is_dir():
            return folder
    return None


def reroot_assets(xml: str, *, where: str, assets: Path | None = None, base: Path | None = None) -> str:
    """The model XML with every asset file that does not exist looked for again, as absolute paths.

    Args:
        xml: the model's XML text.
        where: names the model in errors (file and demonstration).
        assets: a folder to look in: the part of a path after ``models/assets/``, else its name.
        base: the folder relative file names are taken from (default: the current folder).

    Returns:
        ``xml`` itself when every asset file exists as written, else the XML with absolute paths.

    Raises:
        EnergyMarginError: the XML is not XML, or an asset file is found nowhere (one line naming it).
    """
    try:
        root = ElementTree.fromstring(xml)
    except ElementTree.ParseError as error:
        raise EnergyMarginError(f"{where}: model_file: is not valid XML ({_one_line(error)})") from None
    folders: dict[str, str] = {}
    for compiler in root.iter("compiler"):
        for name in ("assetdir", "meshdir", "texturedir"):
            if compiler.get(name):
                folders[name] = str(compiler.get(name))
    robosuite = _robosuite_assets()
    changed = False
    for element in root.iter():
        folder_key = _ASSET_ELEMENTS.get(str(element.tag))
        if folder_key is None:
            continue
        attributes = ("file", *_TEXTURE_FACES) if element.tag == "texture" else ("file",)
        folder = folders.get(folder_key, folders.get("assetdir", ""))
        for attribute in attributes:
            value = element.get(attribute)
            if not value:
                continue
            found = _locate(value, folder, base, assets, robosuite)
            if found is None:
                looked = f" or under {assets}" if assets is not None else ""
                looked += f" or under {robosuite}" if robosuite is not None and assets is None else ""
                raise EnergyMarginError(
                    f"{where}: model_file: {element.tag} file {value} does not exist here{looked}; "
                    "pass `assets`, a folder with the model's asset files (robosuite's models/assets)"
                )
            if found != value:
                element.set(attribute, found)
                changed = True
    return ElementTree.tostring(root, encoding="unicode") if changed else xml


def _locate(value: str, folder: str, base: Path | None, assets: Path | None, robosuite: Path | None) -> str | None:
    """The absolute path of asset file ``value`` (as written, or re-rooted), or ``None``."""
    written = Path(value)
    if not written.is_absolute():
        written = Path(folder) / written
        if not written.is_absolute():
            written = (base or Path.cwd()) / written
    try:
        if written.is_file():
            return value if Path(value).is_absolute() else str(written.resolve())
    except OSError:
        pass
    posix = value.replace("\\", "/")
    candidates: list[Path] = []
    if assets is not None:
        if _MODELS_ASSETS in posix:
            candidates.append(assets / posix.split(_MODELS_ASSETS, 1)[1])
        candidates.append(assets / posix.rsplit("/", 1)[-1])
    if robosuite is not None and _ROBOSUITE_ASSETS in posix:
        candidates.append(robosuite / posix.split(_ROBOSUITE_ASSETS, 1)[1])
    for candidate in candidates:
        try:
            if candidate.is_file():
                return str(candidate.resolve())
        except OSError:
            continue
    return None


def compile_xml(xml: str, *, where: str) -> mujoco.MjModel:
    """Compile model XML with ``mujoco.MjSpec``; a failure is one line with MuJoCo's message."""
    try:
        return mujoco.MjSpec.from_string(xml).compile()
    except (ValueError, mujoco.FatalError) as error:
        raise EnergyMarginError(f"{where}: model_file: does not compile: {_one_line(error)}") from None


def _build_models(path: Path, demos: Sequence[_RawDemo], assets: Path | None) -> list[_BuiltModel]:
    """Each demonstration's model (identical texts compiled once); all must be the first one's."""
    cache: dict[str, _BuiltModel] = {}
    built: list[_BuiltModel] = []
    for demo in demos:
        where = f"{path}:/data/{demo.key}"
        if demo.model_file not in cache:
            xml = reroot_assets(demo.model_file, where=where, assets=assets, base=path.parent)
            model = compile_xml(xml, where=where)
            cache[demo.model_file] = _BuiltModel(xml, model, model_hash(model))
        model_built = cache[demo.model_file]
        if built and model_built.sha256 != built[0].sha256:
            raise EnergyMarginError(
                f"{where}: model_file: compiles to another model than {demos[0].key} "
                f"(sha256 {model_built.sha256[:12]}…, {demos[0].key}: {built[0].sha256[:12]}…); "
                "a dataset has one model: split the file into one file per model"
            )
        built.append(model_built)
    return built
