"""The tutorials' commands work: every ```bash title="Run: ..."``` block of a documentation page is run, in
page order, as one shell script in an empty working directory.

A page shortens its runs for the test with ``<!-- test: sub "TEXT" "REPLACEMENT" -->`` comments (plain text
substitutions applied to the blocks), states what the output must show with ``<!-- test: expect "REGEX" -->``,
and can opt out with ``<!-- test: skip "reason" -->``.  ``gnssrx`` is this checkout's CLI, ``python`` this
interpreter; ``configs/``, ``scripts/`` and ``data/`` of the checkout are linked into the working
directory, and ``../shared`` resolves to the shared data beside the checkout (pages that use it skip when
it is absent).  Every file a command names with ``-o`` must exist afterwards.
"""
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from repo_paths import ROOT
DOCS = ROOT / "docs"
#: the shared data directory (holds data/); GNSSRX_SHARED_DIR overrides the default ../shared beside the checkout
SHARED = Path(os.environ.get("GNSSRX_SHARED_DIR", ROOT.parent / "shared"))

BLOCK = re.compile(r'^```(?:bash|sh)\s+title="Run:[^"]*"\s*\n(.*?)^```\s*$', re.M | re.S)
SUB = re.compile(r'<!--\s*test:\s*sub\s+"((?:[^"\\]|\\.)*)"\s+"((?:[^"\\]|\\.)*)"\s*-->')
EXPECT = re.compile(r'<!--\s*test:\s*expect\s+"((?:[^"\\]|\\.)*)"\s*-->')
SKIP = re.compile(r'<!--\s*test:\s*skip\s+"((?:[^"\\]|\\.)*)"\s*-->')


def tutorial_pages():
    return sorted(p for p in DOCS.rglob("*.md") if BLOCK.search(p.read_text()))


def page_script(text: str) -> str:
    blocks = BLOCK.findall(text)
    subs = SUB.findall(text)
    out = []
    for b in blocks:
        for a, r in subs:
            a, r = a.replace('\\"', '"'), r.replace('\\"', '"')
            assert a in b or any(a in x for x in blocks), f"substitution text not found: {a!r}"
            b = b.replace(a, r)
        out.append(b)
    return "\n".join(out)


def written_files(script: str) -> list:
    """Paths given to -o / --output in the script's commands."""
    files = []
    for line in script.replace("\\\n", " ").splitlines():
        try:
            words = shlex.split(line, comments=True)
        except ValueError:
            continue
        for i, w in enumerate(words[:-1]):
            if w in ("-o", "--output") and not words[i + 1].startswith("$"):
                files.append(words[i + 1])
    return files


def test_pages_have_tutorial_blocks():
    names = {p.relative_to(DOCS).as_posix() for p in tutorial_pages()}
    for page in ("getting-started.md", "own-recording.md", "tutorials/carrier-loops.md",
                 "tutorials/vector-outages.md", "tutorials/multi-gnss.md", "tutorials/high-sensitivity.md",
                 "tutorials/leo.md", "tutorials/paper-figures.md"):
        assert page in names, f"docs/{page} has no Run: block"


def test_script_extraction():
    text = ('intro\n<!-- test: sub "duration_s=40" "duration_s=4" -->\n'
            '```bash title="Run: one"\ngnssrx simulate x.yaml -o out/a.bin --set time.duration_s=40\n```\n'
            '```sh\nnot run\n```\n'
            '```bash title="Run: two"\ngnssrx run out/a.yaml \\\n    -o out/a.h5\n```\n')
    script = page_script(text)
    assert "duration_s=4\n" in script and "not run" not in script
    assert written_files(script) == ["out/a.bin", "out/a.h5"]


@pytest.mark.slow
@pytest.mark.parametrize("page", tutorial_pages(), ids=lambda p: p.relative_to(DOCS).as_posix())
def test_tutorial_runs(page, tmp_path):
    text = page.read_text()
    skip = SKIP.search(text)
    if skip:
        pytest.skip(skip.group(1))
    script = page_script(text)
    if "../shared" in script and not SHARED.is_dir():
        pytest.skip("../shared (the shared recordings) absent")
    work = tmp_path / "work"
    work.mkdir()
    for name in ("configs", "scripts", "data"):
        (work / name).symlink_to(ROOT / name)
    if SHARED.is_dir():
        (tmp_path / "shared").symlink_to(SHARED)
    env = dict(os.environ, PYTHONPATH=str(ROOT), PY=sys.executable, MPLBACKEND="Agg")
    prelude = ('set -euo pipefail\n'
               'gnssrx() { "$PY" -m receiver.cli "$@"; }\n'
               'python() { "$PY" "$@"; }\n')
    proc = subprocess.run(["bash", "-c", prelude + script], cwd=work, env=env, capture_output=True, text=True,
                          timeout=3600)
    log = f"--- stdout\n{proc.stdout[-4000:]}\n--- stderr\n{proc.stderr[-4000:]}"
    assert proc.returncode == 0, log
    for f in written_files(script):
        assert (work / f).exists(), f"{f} was not written\n{log}"
    for pattern in EXPECT.findall(text):
        assert re.search(pattern.replace('\\"', '"'), proc.stdout + proc.stderr, re.M), \
            f"output does not match {pattern!r}\n{log}"
