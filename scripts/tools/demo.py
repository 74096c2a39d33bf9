#!/usr/bin/env python3
"""`make demo`: simulate the default scenario with the embedded constellation, receive it, print the
fix error against the simulator's truth.  Everything lands in out/demo/.

    python scripts/tools/demo.py [--scenario configs/scenarios/static_default.yaml] [--quiet]
"""
import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default=str(ROOT / "configs" / "scenarios" / "static_default.yaml"))
    ap.add_argument("--out", default=str(ROOT / "out" / "demo"))
    ap.add_argument("--quiet", action="store_true")
    args = ap.parse_args()
    from receiver.cli import main as cli
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rec = out / "static.bin"
    q = ["--quiet"] if args.quiet else []
    steps = [
        ("simulate", ["simulate", args.scenario, "-o", str(rec), *q]),
        ("receive", ["run", str(out / "static.yaml"), "-o", str(out / "run.h5"), *q]),
        ("evaluate", ["eval", str(out / "run.h5"), str(out / "static.truth.h5")]),
    ]
    for name, argv in steps:
        print(f"\n== gnssrx {' '.join(argv)}", flush=True)
        try:
            rc = cli.main(argv, standalone_mode=False)
        except SystemExit as exc:
            rc = exc.code
        except Exception as exc:  # noqa: BLE001 - report the failing step in one line
            print(f"demo: step '{name}' failed: {exc}", file=sys.stderr)
            rc = 1
        if rc:
            sys.exit(rc)


if __name__ == "__main__":
    main()
