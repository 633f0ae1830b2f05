"""umqtt.simple, the MQTT client a real board has frozen into its firmware, for a board run by the MicroPython unix
port (the rehearsal board, the tests).

It comes from the PyPI package `micropython-umqtt.simple`, whose sdist pip can neither install nor download (it has no
setup.py): its `umqtt/simple.py` is taken from the sdist the index's JSON API names, checked against the index's
sha256, and kept in a cache folder.
"""

import hashlib
import json
import os
import tarfile
import tempfile
import urllib.request
import zipfile

from cbtc.errors import BoardError

PACKAGE = "micropython-umqtt.simple"
INDEX_JSON = os.environ.get("PYPI_JSON_URL", "https://pypi.org/pypi/%s/json")
MEMBER_SUFFIX = "umqtt/simple.py"


def cache_dir() -> str:
    """Where the fetched module is kept: $XDG_CACHE_HOME/lego-cbtc (default ~/.cache/lego-cbtc)."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "lego-cbtc")


def umqtt_simple(folder: str = None) -> str:
    """The path of `umqtt/simple.py` under `folder` (default: cache_dir()), fetched there first if it is not there
    yet; BoardError saying what to do when it cannot be fetched."""
    folder = folder or cache_dir()
    target = os.path.join(folder, "umqtt", "simple.py")
    if os.path.exists(target):
        return target
    with tempfile.TemporaryDirectory() as tmp:
        source = _extract(_download(tmp))
    os.makedirs(os.path.dirname(target), exist_ok=True)
    with open(os.path.join(os.path.dirname(target), "__init__.py"), "wb"):
        pass
    with open(target + ".part", "wb") as fh:
        fh.write(source)
    os.replace(target + ".part", target)
    return target


def _fetch(url):
    try:
        with urllib.request.urlopen(url, timeout=30) as resp:
            return resp.read()
    except (OSError, ValueError) as exc:
        raise BoardError(f"could not fetch {url} (offline? behind a proxy?): {exc}; or put micropython-lib's "
                         f"umqtt/simple.py into {os.path.join(cache_dir(), 'umqtt')}") from None


def _download(dest):
    """Download the newest sdist of PACKAGE into `dest`; returns its path."""
    meta = json.loads(_fetch(INDEX_JSON % PACKAGE))
    sdists = [f for f in meta.get("urls", []) if f.get("packagetype") == "sdist"]
    if not sdists:
        raise BoardError(f"the package index lists no sdist for {PACKAGE} {meta.get('info', {}).get('version')}")
    entry = sdists[0]
    data = _fetch(entry["url"])
    expected = entry.get("digests", {}).get("sha256")
    if expected and hashlib.sha256(data).hexdigest() != expected:
        raise BoardError(f"{entry['filename']} does not match the index's sha256; try again")
    path = os.path.join(dest, entry["filename"])
    with open(path, "wb") as fh:
        fh.write(data)
    return path


def _extract(archive):
    """The bytes of umqtt/simple.py inside the sdist `archive` (.tar.gz or .zip)."""
    if archive.endswith(".zip"):
        with zipfile.ZipFile(archive) as zf:
            for name in zf.namelist():
                if name.endswith(MEMBER_SUFFIX):
                    return zf.read(name)
    else:
        with tarfile.open(archive) as tf:
            for member in tf.getmembers():
                if member.name.endswith(MEMBER_SUFFIX):
                    return tf.extractfile(member).read()
    raise BoardError(f"{os.path.basename(archive)} holds no {MEMBER_SUFFIX}")
