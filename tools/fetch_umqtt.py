#!/usr/bin/env python3
"""Fetch umqtt.simple (frozen into the ESP8266 firmware) for running the firmware under the MicroPython unix port.

Downloads the sdist of the PyPI package `micropython-umqtt.simple` by name from the index's JSON API (pip can neither
install nor download it: the sdist has no setup.py, and pip wants to read its metadata) and unpacks
`umqtt/simple.py` into the git-ignored folder vendor/umqtt/ at the repository root.
Idempotent: does nothing when the file is already there (use --force to fetch again).
"""

import argparse
import hashlib
import io
import json
import os
import sys
import tarfile
import tempfile
import urllib.request
import zipfile

PACKAGE = "micropython-umqtt.simple"
INDEX_JSON = os.environ.get("PYPI_JSON_URL", "https://pypi.org/pypi/%s/json")
REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TARGET_DIR = os.path.join(REPO, "vendor", "umqtt")
MEMBER_SUFFIX = "umqtt/simple.py"


def _fetch(url):
    try:
        with urllib.request.urlopen(url, timeout=30) as resp:
            return resp.read()
    except (OSError, ValueError) as exc:
        raise SystemExit("fetch_umqtt: could not fetch %s (offline? set a proxy?): %s" % (url, exc)) from None


def _download(dest):
    """Download the newest sdist of PACKAGE into `dest`; returns its path."""
    meta = json.loads(_fetch(INDEX_JSON % PACKAGE))
    sdists = [f for f in meta.get("urls", []) if f.get("packagetype") == "sdist"]
    if not sdists:
        version = meta.get("info", {}).get("version")
        raise SystemExit("fetch_umqtt: the index lists no sdist for %s %s" % (PACKAGE, version))
    entry = sdists[0]
    data = _fetch(entry["url"])
    expected = entry.get("digests", {}).get("sha256")
    if expected and hashlib.sha256(data).hexdigest() != expected:
        raise SystemExit("fetch_umqtt: %s does not match the index's sha256; try again" % entry["filename"])
    path = os.path.join(dest, entry["filename"])
    with io.open(path, "wb") as fh:
        fh.write(data)
    return path


def _extract(archive):
    """The text of umqtt/simple.py inside the sdist `archive` (.tar.gz or .zip)."""
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
    raise SystemExit("fetch_umqtt: %s holds no %s" % (os.path.basename(archive), MEMBER_SUFFIX))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--force", action="store_true", help="download again even if vendor/umqtt/simple.py exists")
    args = parser.parse_args(argv)
    target = os.path.join(TARGET_DIR, "simple.py")
    if os.path.exists(target) and not args.force:
        print("fetch_umqtt: %s already present" % os.path.relpath(target, REPO))
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        source = _extract(_download(tmp))
    os.makedirs(TARGET_DIR, exist_ok=True)
    with io.open(os.path.join(TARGET_DIR, "__init__.py"), "wb"):
        pass
    with io.open(target, "wb") as fh:
        fh.write(source)
    print("fetch_umqtt: wrote %s (%d bytes)" % (os.path.relpath(target, REPO), len(source)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
