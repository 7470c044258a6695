"""Where the tests find the repository, their helpers and data, from any tier's folder.

``ROOT`` is the repository, ``SUPPORT`` this folder (the helpers that tests import by
name, and scripts that subprocess tests run by path), ``DATA`` the tests' recorded
references, ``REALDATA`` the real recordings beside the repository (tests that need them
skip without them).
"""

from pathlib import Path

SUPPORT = Path(__file__).resolve().parent
ROOT = SUPPORT.parents[1]
DATA = SUPPORT / "data"
REALDATA = ROOT.parent / "shared" / "realdata"
