"""The generated configuration references (docs/reference/config.md, docs/reference/scenario.md) and
configs/default.yaml are what scripts/tools/gen_config_docs.py makes from the current schemas, and every key's
full default is in them."""
import importlib.util

import yaml

from repo_paths import ROOT


def _gen():
    (script,) = ROOT.glob("scripts/**/gen_config_docs.py")          # scripts/ or scripts/tools/
    spec = importlib.util.spec_from_file_location("gen_config_docs", script)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_generated_files_are_up_to_date():
    stale = [str(p.relative_to(ROOT)) for p, new in _gen().targets().items()
             if not p.exists() or p.read_text() != new]
    assert not stale, f"{stale} out of date: run scripts/tools/gen_config_docs.py"


def _rows(md: str) -> dict:
    """key -> (type, default, meaning) of the reference tables."""
    rows = {}
    for line in md.splitlines():
        if line.startswith("| `"):
            # split on unescaped pipes only
            cells, cur, i = [], "", 0
            while i < len(line):
                if line[i] == "\\" and i + 1 < len(line) and line[i + 1] == "|":
                    cur += "|"
                    i += 2
                    continue
                if line[i] == "|":
                    cells.append(cur.strip())
                    cur = ""
                else:
                    cur += line[i]
                i += 1
            cells = cells[1:]
            assert len(cells) == 4, line
            rows[cells[0].strip("`")] = tuple(cells[1:])
    return rows


def test_every_key_with_its_full_default():
    from receiver.config import defaults_doc
    from receiver.schema import RECEIVER_SCHEMA
    from receiver.sim.scenario import scenario_doc
    for page, rows in (("config.md", defaults_doc(RECEIVER_SCHEMA)), ("scenario.md", scenario_doc())):
        table = _rows((ROOT / "docs" / "reference" / page).read_text())
        assert set(table) == {r[0] for r in rows}, page
        for key, _kind, default, doc in rows:
            shown = table[key][1].strip("`")
            # the default cell parses back to the schema's default (nothing cut off)
            assert yaml.safe_load(shown) == default, (page, key, shown)
            assert table[key][2].startswith(doc.replace("\n", " ")), (page, key)
            if "(" in _kind and _kind.endswith(")"):       # the choices, in order, after the meaning
                choices = _kind[:-1].split(" (", 1)[1].split("|")
                assert table[key][2].endswith("One of " + ", ".join(f"`{c}`" for c in choices) + "."), key


def test_prns_default_lists_every_prn():
    table = _rows((ROOT / "docs" / "reference" / "config.md").read_text())
    assert yaml.safe_load(table["acquisition.prns"][1].strip("`")) == list(range(1, 33))
