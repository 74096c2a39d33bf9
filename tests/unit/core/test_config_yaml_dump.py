"""Section.to_yaml (the run file's ``config`` attribute) uses libyaml's emitter when available: the text must
be what PyYAML's pure-Python safe dumper writes for every shipped configuration, and load back to the same
values."""
import glob
import os

import yaml

from receiver.schema import load_receiver_config

from repo_paths import ROOT


def test_to_yaml_is_the_safe_dump_of_every_shipped_config():
    n = 0
    for path in sorted(glob.glob(os.path.join(ROOT, "configs", "**", "*.yaml"), recursive=True)):
        try:
            cfg = load_receiver_config(path)
        except Exception:           # scenario files, batch lists: not receiver configurations
            continue
        d = cfg.to_dict()
        text = cfg.to_yaml()
        assert text == yaml.safe_dump(d, sort_keys=False), path
        assert yaml.safe_load(text) == d, path
        n += 1
    assert n >= 10
