"""MkDocs hook: pages other branches add (probe, snapshot, Galileo, validation, plugins, dual frequency).

A page listed in OPTIONAL joins the navigation where it belongs when its file exists under docs/; while it
does not, links to it are rendered as plain text, so ``mkdocs build --strict`` passes either way.
"""
import re
from pathlib import Path

# file -> (title, nav section title or None for the top level, insert after this title)
OPTIONAL = {
    "probe.md": ("Probing an unknown file", None, "Your own recording"),
    "galileo.md": ("Galileo E1", "Tutorials", "BeiDou and multi-GNSS"),
    "dual-frequency.md": ("Dual frequency", "Tutorials", "BeiDou and multi-GNSS"),
    "snapshot.md": ("Snapshot fixes", "Tutorials", "High sensitivity"),
    "validation.md": ("Validation", None, "Benchmarks"),
    "plugins.md": ("Plugins", None, "Contributing"),
}
_present: set = set()


def _title(item):
    return next(iter(item)) if isinstance(item, dict) else None


def _insert(items, title, page, after):
    for i, item in enumerate(items):
        if _title(item) == after:
            items.insert(i + 1, {title: page})
            return True
    items.append({title: page})
    return True


def on_config(config):
    docs = Path(config["docs_dir"])
    nav = config["nav"]
    for page, (title, section, after) in OPTIONAL.items():
        if not (docs / page).exists():
            continue
        _present.add(page)
        if section is None:
            _insert(nav, title, page, after)
            continue
        for item in nav:
            if _title(item) == section:
                _insert(item[section], title, page, after)
    return config


_LINK = re.compile(r"\[([^\]]+)\]\(((?:\.\./)*)([\w-]+\.md)(#[^)]*)?\)")


def on_page_markdown(markdown, page, config, files):
    def plain(m):
        return m.group(1) if m.group(3) in OPTIONAL and m.group(3) not in _present else m.group(0)
    return _LINK.sub(plain, markdown)
