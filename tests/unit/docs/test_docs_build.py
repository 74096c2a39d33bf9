"""The documentation site builds with ``mkdocs build --strict`` (no broken link, no missing nav page, every
API reference resolved).  Skips when mkdocs is not installed (``pip install -r docs/requirements.txt``;
CI builds the site with ``make docs``)."""
import importlib.util
import subprocess
import sys

import pytest

from repo_paths import ROOT


@pytest.mark.slow
def test_site_builds_strict(tmp_path):
    for mod in ("mkdocs", "material", "mkdocstrings", "mkdocstrings_handlers.python"):
        try:
            found = importlib.util.find_spec(mod) is not None
        except ModuleNotFoundError:
            found = False
        if not found:
            pytest.skip(f"{mod} not installed (pip install -r docs/requirements.txt)")
    r = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-q", "-d", str(tmp_path / "site")],
                       cwd=ROOT, capture_output=True, text=True, env={"NO_MKDOCS_2_WARNING": "1",
                                                                     "PATH": "/usr/bin:/bin"})
    assert r.returncode == 0, r.stderr[-3000:]
    for page in ("index.html", "reference/config/index.html", "reference/api/index.html",
                 "tutorials/carrier-loops/index.html", "how-it-works/tracking/index.html"):
        assert (tmp_path / "site" / page).exists(), page
    api = (tmp_path / "site" / "reference" / "api" / "index.html").read_text()
    assert "load_receiver_config" in api and "RunFile" in api       # mkdocstrings rendered the docstrings


def _hook(name):
    spec = importlib.util.spec_from_file_location(name, ROOT / "scripts" / "tools" / "mkdocs_hooks" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_optional_pages_join_the_nav_only_when_present(tmp_path):
    hook = _hook("optional_pages")
    (tmp_path / "snapshot.md").write_text("# Snapshot\n")
    nav = [{"Home": "index.md"}, {"Your own recording": "own-recording.md"},
           {"Tutorials": [{"High sensitivity": "tutorials/high-sensitivity.md"}, {"LEO": "tutorials/leo.md"}]},
           {"Benchmarks": "benchmarks.md"}]
    hook.on_config({"docs_dir": str(tmp_path), "nav": nav})
    assert nav[2]["Tutorials"][1] == {"Snapshot fixes": "snapshot.md"}          # after High sensitivity
    assert all("probe.md" not in str(item) for item in nav)                       # absent: not in the nav
    md = "see [the probe](probe.md) and [snapshots](../snapshot.md) and [LEO](leo.md)"
    assert hook.on_page_markdown(md, None, None, None) == \
        "see the probe and [snapshots](../snapshot.md) and [LEO](leo.md)"


def test_sphinx_roles_are_dropped():
    hook = _hook("sphinx_roles")
    html = 'raises :class:<code>UserError</code>; see :func:<a href="#x">run</a>; ratio 3:4'
    assert hook.on_page_content(html, None, None, None) == \
        'raises <code>UserError</code>; see <a href="#x">run</a>; ratio 3:4'
