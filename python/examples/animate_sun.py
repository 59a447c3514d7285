#!/usr/bin/python3
"""The sun moved every frame, as an animation or a show control script
would: one set per frame, then the frame's snapshot (read-your-writes:
tables() waits for the generation that set named). Prints the frame rate
skyd and this client reach; with --out-dir writes each frame's fisheye.

    animate_sun.py [--socket PATH] [--frames 120] [--size 128] [--out-dir DIR]
"""

import argparse
import math
import os
import time

import skyd


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--socket", help="skyd's control socket (default: as skyctl finds it)")
    ap.add_argument("--frames", type=int, default=120)
    ap.add_argument("--size", type=int, default=128, help="fisheye size in pixels")
    ap.add_argument("--out-dir", help="write frame-NNNN.png files here")
    a = ap.parse_args()
    if a.out_dir:
        os.makedirs(a.out_dir, exist_ok=True)
    with skyd.Client(a.socket) as c:
        t0 = time.monotonic()
        for f in range(a.frames):
            # Sunrise in the east to sunset in the west along an arc.
            x = f / max(a.frames - 1, 1)
            el, az = -4.0 + 60.0 * math.sin(math.pi * x), 90.0 + 180.0 * x
            g = c.set(sun_elevation_deg=el, sun_azimuth_deg=az)
            snap = c.tables("skyview", "transmittance")
            if a.out_dir:
                img = snap.fisheye(a.size, yaw_deg=180.0, sun_disk=True)
                skyd.image.write_png(os.path.join(a.out_dir, "frame-%04d.png" % f),
                                     skyd.image.to_srgb8(img, scale=0.18 / 3000.0))
            # The sun as the frame's tables have it (the generation set named, or later).
            print("frame %d: sun %.2f deg az %.1f, generation %d (asked %d), zenith %.1f cd/m2"
                  % (f, snap.state.sun_elevation_deg, snap.state.sun_azimuth_deg,
                     snap.generation, g, skyd.image.luminance(snap.sky_radiance(90, 0))))
        dt = time.monotonic() - t0
    print("%d frames in %.2f s: %.1f frames/s" % (a.frames, dt, a.frames / dt))


if __name__ == "__main__":
    main()
