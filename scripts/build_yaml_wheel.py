"""Build wheels/pyyaml-<version>-py3-none-any.whl, the PyYAML the extension ships.

Unity's .mat files are read with PyYAML (addon/core/unity/read.py), which Blender does not
bundle. PyPI publishes PyYAML as per-platform wheels (with its optional C extension) and as a
source archive; the extension needs one wheel for every platform, so this script takes the
pure-Python package ``lib/yaml/`` out of the official source archive (MIT licence, kept in the
wheel) and writes it as a ``py3-none-any`` wheel, byte for byte the same on every run (fixed
timestamps, sorted entries). PyYAML falls back to its pure-Python loader when ``yaml._yaml`` is
absent, which is what the add-on uses (SafeLoader).

    ./scripts/dev.sh build_yaml_wheel

The archive is fetched with pip from the package index and checked against SHA256 below.
"""

import base64
import hashlib
import subprocess
import sys
import tarfile
import tempfile
import zipfile
from pathlib import Path

VERSION = "6.0.4"
SHA256 = "e24bf71af8a432d7808fabff134d38dfe16d3cbb41f2873bb4b1e42422de0a1a"
ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "wheels" / f"pyyaml-{VERSION}-py3-none-any.whl"
DIST_INFO = f"pyyaml-{VERSION}.dist-info"
STAMP = (2020, 1, 1, 0, 0, 0)


def _record_line(name: str, data: bytes) -> str:
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
    return f"{name},sha256={digest},{len(data)}"


def _sdist(folder: Path) -> Path:
    subprocess.run(
        [sys.executable, "-m", "pip", "download", "--no-deps", "--no-binary", ":all:"]
        + [f"pyyaml=={VERSION}", "-d", str(folder)],
        check=True,
        capture_output=True,
    )
    archive = folder / f"pyyaml-{VERSION}.tar.gz"
    if hashlib.sha256(archive.read_bytes()).hexdigest() != SHA256:
        sys.exit(f"{archive.name}: its SHA256 is not the one recorded here")
    return archive


def build() -> Path:
    with tempfile.TemporaryDirectory() as tmp:
        archive = _sdist(Path(tmp))
        files = {}
        with tarfile.open(archive) as tar:
            for member in tar.getmembers():
                parts = Path(member.name).parts
                source = parts[1:3] == ("lib", "yaml") and member.name.endswith(".py")
                if member.isfile() and source:
                    files["yaml/" + "/".join(parts[3:])] = tar.extractfile(member).read()
                elif member.isfile() and parts[1:] in (("LICENSE",), ("PKG-INFO",)):
                    files[parts[1]] = tar.extractfile(member).read()
    metadata = files.pop("PKG-INFO")
    files[f"{DIST_INFO}/licenses/LICENSE"] = files.pop("LICENSE")
    files[f"{DIST_INFO}/METADATA"] = metadata
    files[f"{DIST_INFO}/WHEEL"] = (
        b"Wheel-Version: 1.0\nGenerator: cook-torrance-lab build_yaml_wheel.py\n"
        b"Root-Is-Purelib: true\nTag: py3-none-any\n"
    )
    files[f"{DIST_INFO}/top_level.txt"] = b"yaml\n"
    record = [_record_line(n, d) for n, d in sorted(files.items())] + [f"{DIST_INFO}/RECORD,,"]
    files[f"{DIST_INFO}/RECORD"] = ("\n".join(record) + "\n").encode()
    OUT.parent.mkdir(exist_ok=True)
    partial = OUT.with_suffix(".partial")
    with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as whl:
        for name, data in sorted(files.items()):
            info = zipfile.ZipInfo(name, STAMP)
            info.external_attr = 0o644 << 16
            info.compress_type = zipfile.ZIP_DEFLATED
            whl.writestr(info, data)
    partial.replace(OUT)
    return OUT


if __name__ == "__main__":
    print(build().relative_to(ROOT))
