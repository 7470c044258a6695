"""Importing SynSense's samna safely: the real library, or one line saying why not.

The ``samna`` wheel on PyPI is a placeholder that pip-installs the real library from
SynSense's GitLab index *at import time* and fails offline. :func:`import_samna`
recognises that placeholder from its source without running it and says what to
install (:class:`SamnaUnavailableError`). samna is imported only inside ``hardware/``,
lazily, through this function: never at module import.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from pathlib import Path
from types import ModuleType

__all__ = ["SamnaUnavailableError", "import_samna"]

_STUB_MARKERS = ("PYPI_SAMNA", "install_real_samna")
_REAL_SAMNA_HINT = (
    "install the real samna from SynSense (needs network access): "
    "`pip install --force-reinstall samna==<version> "
    "--index-url https://gitlab.com/api/v4/projects/27423070/packages/pypi/simple` "
    "(or run `python -c 'import samna'` once while online); "
    "see https://synsense-sys-int.gitlab.io/samna/install.html"
)


class SamnaUnavailableError(RuntimeError):
    """The real samna library cannot be used: missing, the PyPI placeholder, or broken."""


def _is_stub_source(path: str | None) -> bool:
    if not path or not path.endswith(".py"):
        return False
    try:
        text = Path(path).read_text(errors="replace")[:65536]
    except OSError:
        return False
    return all(marker in text for marker in _STUB_MARKERS)


def import_samna() -> ModuleType:
    """Import the real samna, or raise :class:`SamnaUnavailableError` saying why.

    The PyPI placeholder is recognised from its source *before* it runs (it would
    start ``pip install`` at import time); a module already in ``sys.modules`` is
    used as is unless it is that placeholder.
    """
    if "samna" in sys.modules:
        module = sys.modules["samna"]
        if module is None:
            raise SamnaUnavailableError(
                f"samna is not installed (import blocked); {_REAL_SAMNA_HINT}"
            )
    else:
        try:
            spec = importlib.util.find_spec("samna")
        except (ImportError, ValueError) as err:
            raise SamnaUnavailableError(
                f"samna cannot be located ({err}); {_REAL_SAMNA_HINT}"
            ) from err
        if spec is None:
            raise SamnaUnavailableError(
                f"samna is not installed; the Speck source needs it. {_REAL_SAMNA_HINT}"
            )
        if _is_stub_source(spec.origin):
            raise SamnaUnavailableError(
                f"the installed samna ({spec.origin}) is SynSense's PyPI placeholder, which "
                "pip-installs the real library at import time (fails offline); it was not "
                f"imported. {_REAL_SAMNA_HINT}"
            )
        try:
            module = importlib.import_module("samna")
        except ImportError as err:
            raise SamnaUnavailableError(
                f"samna is installed but failed to import ({err!r}); {_REAL_SAMNA_HINT}"
            ) from err
        except Exception as err:  # the placeholder's pip subprocess, network errors, ...
            raise SamnaUnavailableError(
                f"importing samna failed ({err!r}); this is what the PyPI placeholder does when "
                f"it cannot download the real library. {_REAL_SAMNA_HINT}"
            ) from err
    if getattr(module, "PYPI_SAMNA", False) or not hasattr(module, "device"):
        raise SamnaUnavailableError(
            f"the imported samna ({getattr(module, '__file__', module)!r}) is the PyPI "
            f"placeholder or incomplete (no samna.device); {_REAL_SAMNA_HINT}"
        )
    return module
