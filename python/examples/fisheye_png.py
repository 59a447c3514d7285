#!/usr/bin/python3
"""The sky of the current generation as a planetarium dome master, written
to PNG: the snapshot rendered as a fisheye in numpy (zenith at the centre,
the front azimuth at the bottom), tone-mapped to sRGB and written with
zlib alone.

    fisheye_png.py [--socket PATH] [--size 512] [--yaw 180] [--ev100 EV]
                   [--no-disks] [--out sky.png]
"""

import argparse

import skyd


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--socket", help="skyd's control socket (default: as skyctl finds it)")
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--yaw", type=float, default=180.0, help="azimuth at the bottom of the dome")
    ap.add_argument("--ev100", type=float,
                    help="exposure (EV100; default: the mean sky at middle grey)")
    ap.add_argument("--no-disks", action="store_true", help="leave out the sun and the moon")
    ap.add_argument("--out", default="sky.png")
    a = ap.parse_args()
    with skyd.Client(a.socket) as c:
        snap = c.tables("skyview", "transmittance")
    disks = not a.no_disks
    img = snap.fisheye(a.size, yaw_deg=a.yaw, sun_disk=disks, moon_disk=disks,
                       limb_darkening=disks)
    # EV100 to a scale: the luminance that a meter would make middle grey.
    scale = None if a.ev100 is None else 0.18 / (12.5 * 2.0 ** a.ev100 / 100.0)
    skyd.image.write_png(a.out, skyd.image.to_srgb8(img, scale))
    print("%s: %dx%d fisheye of generation %d (sun at %.1f deg)"
          % (a.out, a.size, a.size, snap.generation, snap.state.sun_elevation_deg))


if __name__ == "__main__":
    main()
