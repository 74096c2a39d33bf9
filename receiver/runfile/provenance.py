"""Provenance attributes of a run file: package versions, the git commit of the code when it runs from a
git checkout, and the input file's size and a content hash of its first MB (identifies the recording
without reading all of it)."""
from __future__ import annotations

import hashlib
import json
import os
import subprocess
from importlib import metadata

PACKAGES = ("numpy", "scipy", "numba", "h5py", "pyyaml", "click")
HASH_BYTES = 1 << 20


def package_versions() -> str:
    out = {}
    for p in PACKAGES:
        try:
            out[p] = metadata.version(p)
        except metadata.PackageNotFoundError:
            out[p] = "absent"
    return json.dumps(out, sort_keys=True)


def git_commit() -> str:
    """The commit of the code's checkout ('' when not in a git checkout or git is absent)."""
    here = os.path.dirname(os.path.abspath(__file__))
    try:
        r = subprocess.run(["git", "-C", here, "rev-parse", "HEAD"], capture_output=True, text=True,
                           timeout=5)
    except (OSError, subprocess.SubprocessError):
        return ""
    if r.returncode != 0:
        return ""
    dirty = subprocess.run(["git", "-C", here, "status", "--porcelain", "--untracked-files=no"],
                           capture_output=True, text=True, timeout=5).stdout.strip()
    return r.stdout.strip() + ("-dirty" if dirty else "")


def input_provenance(path) -> dict:
    with open(path, "rb") as fh:
        head = fh.read(HASH_BYTES)
    return {"input_size_bytes": os.path.getsize(path),
            "input_sha256_first_mb": hashlib.sha256(head).hexdigest()}


def provenance(input_path) -> dict:
    return {"package_versions": package_versions(), "git_commit": git_commit(), **input_provenance(input_path)}
