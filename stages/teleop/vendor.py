"""Vendor the page's JavaScript dependency from the npm registry: IWER (the Immersive Web Emulation
Runtime, MIT), which emulates a WebXR headset with hand tracking in a desktop browser (the browser
test's headset; ``?emulate=1`` on the page).

``python -m stages.teleop.vendor`` runs ``npm install iwer@<IWER_VERSION>`` in a temporary folder
(npm checks the package's registry integrity hash) and copies its UMD build and licence into
``stages/teleop/page/vendor/`` (not in git: made at install time by ``make install`` and
``.ci/run``). Nothing is fetched at run time; the server serves the copy.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

IWER_VERSION = "2.5.0"
VENDOR = Path(__file__).resolve().parent / "page" / "vendor"
FILES = {"build/iwer.min.js": "iwer.min.js", "LICENSE": "IWER-LICENSE.txt"}


def vendored() -> Path | None:
    """The vendored IWER script if present and of the pinned version, else None."""
    js, stamp = VENDOR / "iwer.min.js", VENDOR / "iwer.json"
    try:
        ok = js.is_file() and json.loads(stamp.read_text())["version"] == IWER_VERSION
    except (OSError, ValueError, KeyError):
        ok = False
    return js if ok else None


def vendor_iwer(*, npm: str = "npm") -> Path:
    """Install IWER from the npm registry and copy it into the package; returns the script's path."""
    if vendored() is not None:
        return VENDOR / "iwer.min.js"
    exe = shutil.which(npm)
    if exe is None:
        raise RuntimeError("npm not found: install Node.js (apt-get install nodejs npm) to vendor IWER")
    with tempfile.TemporaryDirectory(prefix="iwer-") as tmp:
        subprocess.run([exe, "install", "--no-audit", "--no-fund", "--ignore-scripts", "--prefix", tmp,
                        f"iwer@{IWER_VERSION}"], check=True, capture_output=True, text=True, timeout=600)
        pkg = Path(tmp) / "node_modules" / "iwer"
        version = json.loads((pkg / "package.json").read_text())["version"]
        if version != IWER_VERSION:
            raise RuntimeError(f"npm installed iwer {version}, expected {IWER_VERSION}")
        VENDOR.mkdir(parents=True, exist_ok=True)
        for src, dst in FILES.items():
            shutil.copyfile(pkg / src, VENDOR / dst)
        (VENDOR / "iwer.json").write_text(json.dumps({"package": "iwer", "version": version, "license": "MIT"}))
    return VENDOR / "iwer.min.js"


def main() -> int:
    try:
        path = vendor_iwer()
    except (RuntimeError, OSError, subprocess.SubprocessError) as e:
        print(f"teleop vendor: {e}", file=sys.stderr)
        return 1
    print(f"teleop vendor: IWER {IWER_VERSION} at {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
