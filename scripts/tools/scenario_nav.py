"""Write the RINEX 3 navigation file of what a simulator scenario broadcasts (every system: Gnn / Jnn / Enn / Cnn
records, mixed for several systems), for ``navigation.ephemeris`` (assisted mode: every system used from the
first seconds instead of after its ephemerides are decoded; receiver.sim.simulate.write_broadcast_nav).

    PYTHONPATH=. python scripts/tools/scenario_nav.py SCENARIO.yaml OUT.nav [--set KEY=VALUE ...]
"""
import argparse

from receiver.sim.simulate import write_broadcast_nav


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario")
    ap.add_argument("out")
    ap.add_argument("--set", dest="sets", action="append", default=[], help="scenario KEY=VALUE")
    a = ap.parse_args(argv)
    n = write_broadcast_nav(a.scenario, a.out, a.sets)
    print(f"{a.out}: {n} records")


if __name__ == "__main__":
    main()
