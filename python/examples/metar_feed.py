#!/usr/bin/python3
"""A METAR feed applied to the sky: each report in a file (one a line; #
comments and blank lines skipped) goes to skyd as set metar="...", and the
sky it makes is reported: what skyd used, the zenith luminance, the light
on the ground. --follow keeps reading the file as a feed appends to it.

    metar_feed.py [--socket PATH] [--interval S] [--follow] REPORTS.txt
"""

import argparse
import time

import skyd


def reports(path, follow):
    with open(path) as f:
        while True:
            line = f.readline()
            if not line:
                if not follow:
                    return
                time.sleep(1.0)         # a file has no event to wait on
                continue
            line = line.strip()
            if line and not line.startswith("#"):
                yield line


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--socket", help="skyd's control socket (default: as skyctl finds it)")
    ap.add_argument("--interval", type=float, default=0.0, help="seconds between reports")
    ap.add_argument("--follow", action="store_true", help="wait for lines appended to the file")
    ap.add_argument("file")
    a = ap.parse_args()
    refused = 0
    with skyd.Client(a.socket) as c:
        for n, report in enumerate(reports(a.file, a.follow)):
            if n and a.interval:
                time.sleep(a.interval)
            try:
                r = c.metar(report)
            except skyd.SkyError as e:
                refused += 1
                print("refused: %s\n  %s" % (report, e))
                continue
            snap = c.tables("skyview", "transmittance")
            applied = r["metar_applied"]
            if isinstance(applied, dict):
                applied = " ".join("%s=%s" % kv for kv in applied.items())
            print("%s\n  used: %s\n  applied: %s\n  generation %d: zenith %.0f cd/m2, sky %.0f lx, "
                  "sun %.0f lx" % (report, r.get("metar_used"), applied, snap.generation,
                                   skyd.image.luminance(snap.sky_radiance(90, 0)),
                                   skyd.image.luminance(snap.ambient_illuminance()),
                                   skyd.image.luminance(snap.sun_illuminance())))
    if refused:
        print("%d report(s) refused" % refused)


if __name__ == "__main__":
    main()
