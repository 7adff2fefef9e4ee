"""Names a package exports without importing their modules until first use.

A stage's ``__init__`` lists its public names and the modules that define them; importing the
package stays cheap (no MuJoCo, no scikit-learn) and the first use of a name imports its module.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["lazy_getattr"]


def lazy_getattr(package: str, homes: Mapping[str, str | tuple[str, str]]) -> Callable[[str], Any]:
    """A module ``__getattr__`` that loads each name of ``homes`` from its module on first use.

    Args:
        package: the package's dotted name (for the error of an unknown name).
        homes: public name -> the module that defines it under that name, or ``(module, name there)``.

    """

    def module_getattr(name: str) -> Any:
        home = homes.get(name)
        if home is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module, attribute = (home, name) if isinstance(home, str) else home
        return getattr(importlib.import_module(module), attribute)

    return module_getattr
