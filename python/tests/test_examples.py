"""The examples in python/examples, each run for a moment against the real skyd
so that they cannot rot: their output files and what they print."""

import os
import subprocess
import sys

import numpy as np
import pytest

import skyd

EXAMPLES = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "examples")


def example(daemon, name, *args):
    r = subprocess.run([sys.executable, os.path.join(EXAMPLES, name), "--socket", daemon.socket]
                       + list(args), capture_output=True, text=True, timeout=240)
    assert r.returncode == 0, r.stdout + r.stderr
    return r.stdout


def test_fisheye_png(daemon, tmp_path):
    out = tmp_path / "sky.png"
    text = example(daemon, "fisheye_png.py", "--size", "64", "--out", str(out))
    assert text.startswith("%s: 64x64 fisheye of generation " % out)
    img = skyd.image.read_png(out)
    assert img.shape == (64, 64, 3)
    assert (img[0, 0] == 0).all() and img[32, 32].sum() > 0      # outside and inside the dome
    example(daemon, "fisheye_png.py", "--size", "16", "--ev100", "12", "--no-disks",
            "--out", str(out))
    assert skyd.image.read_png(out).shape == (16, 16, 3)


def test_animate_sun(daemon, tmp_path):
    text = example(daemon, "animate_sun.py", "--frames", "3", "--size", "24",
                   "--out-dir", str(tmp_path))
    lines = text.splitlines()
    assert [line.split(":")[0] for line in lines[:3]] == ["frame 0", "frame 1", "frame 2"]
    assert "sun 56.00 deg az 180.0" in lines[1]                   # the arc's top, at noon
    assert lines[3].startswith("3 frames in ")
    frames = sorted(os.listdir(tmp_path))
    assert frames == ["frame-0000.png", "frame-0001.png", "frame-0002.png"]
    noon = skyd.image.read_png(tmp_path / frames[1]).astype(int)
    dusk = skyd.image.read_png(tmp_path / frames[2]).astype(int)
    assert noon.sum() > dusk.sum()


def test_metar_feed(daemon, tmp_path):
    feed = tmp_path / "feed.txt"
    feed.write_text(open(os.path.join(EXAMPLES, "metar.txt")).read()
                    + "\n# a bad one\nEGLL 241250Z 27008KT 9999X FEW030\n")
    text = example(daemon, "metar_feed.py", str(feed))
    assert text.count("  used: ") == 6
    assert "applied: visibility_km=1.5 relative_humidity=1 aerosol=maritime cloud_oktas=8" in text
    assert "refused: EGLL 241250Z 27008KT 9999X FEW030" in text
    assert text.rstrip().endswith("1 report(s) refused")
    with skyd.Client(daemon.socket) as c:
        assert c.get("aerosol") == "desert"                       # the last report's dust
        c.set(visibility_km="auto", relative_humidity="auto", aerosol="auto", cloud_oktas="auto")


def test_day_plot(daemon, tmp_path):
    pytest.importorskip("matplotlib")
    out = tmp_path / "day.png"
    text = example(daemon, "day_plot.py", "--steps", "5", "--date", "2026-06-21",
                   "--lat", "48.85", "--lon", "2.35", "--out", str(out))
    assert text.startswith("%s: 5 samples; brightest zenith " % out)
    assert "at 12.0 h" in text                                     # noon in Paris, in UTC
    with open(out, "rb") as f:
        assert f.read(8) == b"\x89PNG\r\n\x1a\n"
    with skyd.Client(daemon.socket) as c:
        assert c.get("sun_mode") == "clock"
        assert np.isclose(c.get("lat_deg"), 48.85)
