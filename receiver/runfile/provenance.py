"""Provenance attributes of a run file: package versions, the git commit of the code when it runs from a
git checkout, the CPU the compiled kernels were built for, and the input file's size and a content hash of
its first MB (identifies the recording without reading all of it)."""
from __future__ import annotations

import hashlib
import json
import os
import subprocess
import threading
from importlib import metadata

PACKAGES = ("numpy", "scipy", "numba", "h5py", "pyyaml", "click")
HASH_BYTES = 1 << 20


def package_versions() -> str:
    """Installed versions of the :data:`PACKAGES` as a JSON object ('absent' for a package not installed)."""
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


def cpu_target() -> str:
    """The CPU the compiled (numba) kernels target and the machine's CPU model, e.g. ``"znver3 (host); AMD
    EPYC"`` or ``"generic (NUMBA_CPU_NAME); ..."``.  numba compiles for the host CPU (its vector widths, fused
    multiply-add, ...), so the same code, configuration and recording can give results that differ in
    their last digits on another machine (docs/reference/runfile-format.md); this tells two run files'
    machines apart.  '' when neither can be read."""
    name = os.environ.get("NUMBA_CPU_NAME", "").strip()
    if name:
        name += " (NUMBA_CPU_NAME)"
    else:
        try:
            import llvmlite.binding as llvm
            name = f"{llvm.get_host_cpu_name()} (host)"
        except Exception:  # noqa: BLE001 - provenance must not stop a run
            name = ""
    model = ""
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.lower().startswith("model name"):
                    model = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return "; ".join(p for p in (name, model) if p)


def input_provenance(path) -> dict:
    """Size (bytes) and SHA-256 of the first MB of the input file, as run-file attributes."""
    with open(path, "rb") as fh:
        head = fh.read(HASH_BYTES)
    return {"input_size_bytes": os.path.getsize(path),
            "input_sha256_first_mb": hashlib.sha256(head).hexdigest()}


def provenance(input_path) -> dict:
    """All provenance attributes of a run: package versions, git commit, CPU target, input size and hash."""
    return {"package_versions": package_versions(), "git_commit": git_commit(), "cpu": cpu_target(),
            **input_provenance(input_path)}


def provenance_async():
    """Start :func:`package_versions` and :func:`git_commit` on a thread (git runs as two subprocesses,
    20-50 ms of wall that the run's start-up need not wait for); returns ``result(input_path)``, which
    waits for them and gives the :func:`provenance` dict."""
    out: dict = {}

    def work():
        try:
            out["package_versions"] = package_versions()
            out["git_commit"] = git_commit()
            out["cpu"] = cpu_target()
        except BaseException as exc:  # noqa: BLE001 - raised again in the caller
            out["error"] = exc

    t = threading.Thread(target=work, name="gnssrx-provenance", daemon=True)
    t.start()

    def result(input_path) -> dict:
        t.join()
        if "error" in out:
            raise out["error"]
        return {"package_versions": out["package_versions"], "git_commit": out["git_commit"],
                "cpu": out["cpu"], **input_provenance(input_path)}
    return result
