#!/usr/bin/python3
"""A day's sky over a place, plotted: skyd's clock steps through the day
(sun_mode=clock at a frozen time_rate), and for each step the snapshot's
zenith luminance, horizontal sky and sun illuminance and the zenith's
colour go on a chart written as a PNG with matplotlib (Agg, no display).

    day_plot.py [--socket PATH] [--date 2026-06-21] [--lat 48.85] [--lon 2.35]
                [--steps 97] [--out day.png]
"""

import argparse
import datetime

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after the backend)
import numpy as np  # noqa: E402

import skyd  # noqa: E402


def sample_day(c, day, steps):
    """(hours, sun elevation, zenith cd/m2, sky lx, sun lx, zenith rgb) per step."""
    start = datetime.datetime.combine(day, datetime.time(), datetime.timezone.utc)
    rows = []
    for i in range(steps):
        t = start + datetime.timedelta(days=1) * i / max(steps - 1, 1)
        c.set(utc=t)
        snap = c.tables("skyview", "transmittance")
        zenith = snap.sky_radiance(90.0, 0.0)
        rows.append((i * 24.0 / max(steps - 1, 1), snap.state.sun_elevation_deg,
                     skyd.image.luminance(zenith), skyd.image.luminance(snap.ambient_illuminance()),
                     skyd.image.luminance(snap.sun_illuminance()), zenith))
    return rows


def plot(rows, title, out):
    hours = np.array([r[0] for r in rows])
    fig, (ax, strip) = plt.subplots(2, 1, figsize=(9, 6), sharex=True,
                                    gridspec_kw={"height_ratios": [4, 1]})
    floor = 1e-6                      # a log axis: the night floor and the sun below it
    ax.semilogy(hours, np.maximum([r[2] for r in rows], floor), label="zenith luminance (cd/m2)")
    ax.semilogy(hours, np.maximum([r[3] for r in rows], floor), label="sky on the ground (lx)")
    ax.semilogy(hours, np.maximum([r[4] for r in rows], floor), label="sun, facing it (lx)")
    ax.set_ylim(floor, 2e5)
    elev = ax.twinx()
    elev.plot(hours, [r[1] for r in rows], "k:", label="sun elevation (deg)")
    elev.set_ylabel("sun elevation (deg)")
    ax.set_title(title)
    ax.legend(loc="upper left", fontsize="small")
    ax.grid(True, which="major", alpha=0.3)
    # The zenith's colour: its chromaticity at a fixed brightness.
    rgb = np.array([r[5] for r in rows])
    chroma = rgb / np.maximum(rgb.max(axis=1, keepdims=True), 1e-30)
    strip.imshow(chroma[None] ** (1 / 2.2), aspect="auto", extent=(hours[0], hours[-1], 0, 1))
    strip.set_yticks([])
    strip.set_xlabel("hour (UTC)")
    strip.set_title("zenith colour", fontsize="small")
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--socket", help="skyd's control socket (default: as skyctl finds it)")
    ap.add_argument("--date", type=datetime.date.fromisoformat,
                    default=datetime.date(2026, 6, 21))
    ap.add_argument("--lat", type=float, default=48.85)
    ap.add_argument("--lon", type=float, default=2.35)
    ap.add_argument("--steps", type=int, default=97, help="samples over the 24 hours")
    ap.add_argument("--out", default="day.png")
    a = ap.parse_args()
    with skyd.Client(a.socket) as c:
        c.set(time_rate=0, lat_deg=a.lat, lon_deg=a.lon, sun_mode="clock", moon_mode="clock")
        rows = sample_day(c, a.date, max(a.steps, 2))
    plot(rows, "%s at %.2f, %.2f" % (a.date, a.lat, a.lon), a.out)
    peak = max(rows, key=lambda r: r[2])
    print("%s: %d samples; brightest zenith %.0f cd/m2 at %.1f h (sun at %.1f deg)"
          % (a.out, len(rows), peak[2], peak[0], peak[1]))


if __name__ == "__main__":
    main()
