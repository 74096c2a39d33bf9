#!/usr/bin/env python
"""Write the synthetic Iridium-NEXT-like TLE set data/iridium_synthetic.tle.

66 satellites in 6 near-polar planes (inclination 86.4 deg, ~780 km altitude, 11 satellites per plane),
Walker-star geometry: ascending nodes 31.6 deg apart (the 22 deg "seam" between the counter-rotating
planes 1 and 6 closes the 180 deg), neighbouring planes phased by half the in-plane spacing.
Epoch 2022-04-05 00:00:00 UTC.  Satellite numbers 90001-90066 (not real objects).

    python scripts/tools/make_leo_tles.py [-o data/iridium_synthetic.tle] [--raan0 DEG]
"""
import os

import click


from receiver.leo.constellation import (format_tle_file, parse_tle_text,  # noqa: E402
                                        walker_star_tles)


@click.command()
@click.option("-o", "--output", default=os.path.join(os.path.dirname(__file__), "..", "..", "data",
                                                     "iridium_synthetic.tle"), show_default=True)
@click.option("--epoch", default="2022-04-05T00:00:00", show_default=True)
@click.option("--raan0", default=20.0, show_default=True, help="RAAN of plane 1 (deg)")
@click.option("--altitude-km", default=780.0, show_default=True)
@click.option("--inclination", default=86.4, show_default=True)
def main(output, epoch, raan0, altitude_km, inclination):
    tles = walker_star_tles(epoch, n_planes=6, per_plane=11, inclination_deg=inclination,
                            altitude_km=altitude_km, raan0_deg=raan0, raan_spacing_deg=31.6)
    text = format_tle_file(tles)
    parse_tle_text(text, output)            # round-trip check: lengths and checksums
    with open(output, "w") as fh:
        fh.write(text)
    click.echo(f"wrote {len(tles)} TLEs to {output}")


if __name__ == "__main__":
    main()
