"""Sampling in numpy against the C: skyd's sample verb and libsky's CPU
sampling (through pyprobe, on a snapshot of the same generation), for both
storages. The bound is one float32 rounding, relative: 2**-23 of the
larger value per channel (the C computes in double like this package; the
verb prints 9 digits, sky_render stores float32)."""

import math
import subprocess

import numpy as np
import pytest

import skyd

BOUND = 2.0 ** -23

SKY_EL = [-90, -30, -5, -0.5, 0, 0.3, 2, 10, 20, 45, 89.9, 90]
SKY_AZ = [0, 37.5, 135, 180, 359.9, -20, 400]
TRANS = [(alt, mu) for alt in (0, 0.2, 5, 50, 99.9) for mu in (-0.2, 0, 0.1, 0.5, 1)]
AERIAL = [(u, v, d) for u in (0, 0.3, 1) for v in (0.05, 0.5, 0.97)
          for d in (0, 0.5, 3, 10, 31.9, 50)]
DIRS = [(0, 1, 0), (0.3, -0.8, 0.1), (-1, 0.2, -0.05), (0.1, 0.1, 0.99), (0.7, 0.7, 0)]
RENDERS = [("fisheye", 24, 24, 30, 0, 0, 60, 3), ("equirect", 32, 16, 0, 0, 0, 60, 1),
           ("perspective", 24, 16, 135, 20, 5, 70, 7)]
MEASURED = {}


def rel_error(got, want):
    got, want = np.asarray(got, np.float64), np.asarray(want, np.float64)
    scale = np.maximum(np.abs(got), np.abs(want))
    with np.errstate(invalid="ignore", divide="ignore"):
        r = np.where(scale > 0, np.abs(got - want) / scale, 0.0)
    return float(r.max())


def agree(what, got, want):
    e = rel_error(got, want)
    MEASURED[what] = max(MEASURED.get(what, 0.0), e)
    assert e <= BOUND, "%s: relative error %.3g over %.3g" % (what, e, BOUND)


@pytest.fixture(scope="module", params=["f32", "f16"])
def scene(request, daemon):
    """A sky with a lit moon, a camera and two views (held by this
    connection), in the storage of the parameter."""
    c = skyd.Client(daemon.socket, timeout=60)
    c.set(storage=request.param, sun_elevation_deg=20, sun_azimuth_deg=135,
          moon_elevation_deg=30, moon_azimuth_deg=250, moon_illuminance_lx=0.3,
          moon_angular_radius_deg=2, sun_angular_radius_deg=1.5,
          camera_yaw_deg=200, camera_pitch_deg=10, camera_vfov_deg=50)
    c.view_add("left", yaw_deg=135, vfov_deg=45)
    c.view_add("wall0", form="panorama", yaw_deg=0, vfov_deg=40, aspect=1.6)
    snap = c.tables()
    assert snap.layout["skyview"].format == ("rgba16f" if request.param == "f16" else "rgba32f")
    yield c, snap
    c.close()


def libsky(probe, socket, generation, lines):
    """pyprobe's answers, one list of floats per output line, for a snapshot
    of exactly this generation (None when skyd has moved on)."""
    out = subprocess.run([probe, socket, str(generation)], input="\n".join(lines) + "\n",
                         capture_output=True, text=True, check=True).stdout.splitlines()
    if int(out[0].split()[1]) != generation:
        return None
    return [[float(x) for x in line.split()] for line in out[1:]]


def test_sample_verb_agrees(scene):
    c, snap = scene
    for el in SKY_EL:
        for az in SKY_AZ:
            s = c.sample("sky", el_deg=el, az_deg=az)
            assert s.generation == snap.generation
            agree("sample sky", snap.sky_radiance(el, az), s.rgb)
            agree("sample sky luminance", skyd.image.luminance(snap.sky_radiance(el, az)), s.value)
    agree("sample sun", snap.sun_illuminance(), c.sample("sun").rgb)
    agree("sample ambient", snap.ambient_illuminance(), c.sample("ambient").rgb)


def test_vectorised_sampling_is_pointwise(scene):
    _, snap = scene
    el, az = np.meshgrid(SKY_EL, SKY_AZ, indexing="ij")
    grid = snap.sky_radiance(el, az)
    assert grid.shape == el.shape + (3,)
    for i, e in enumerate(SKY_EL):
        for j, a in enumerate(SKY_AZ):
            assert np.array_equal(grid[i, j], snap.sky_radiance(e, a))


def test_libsky_agrees(scene, probe, daemon):
    c, snap = scene
    st = snap.state
    sun_el, sun_az = st.sun_elevation_deg, st.sun_azimuth_deg
    near_sun = [(sun_el + de, sun_az + da) for de in (-1, 0, 0.5) for da in (-1, 0, 0.7)]
    lines = ["sky %r %r 0" % (e, a) for e in SKY_EL for a in SKY_AZ]
    lines += ["sky %r %r 7" % p for p in near_sun] + ["sky 30 250 2", "sky 29.5 251 3"]
    lines += ["trans %r %r" % t for t in TRANS] + ["sun", "ambient"]
    lines += ["aerial %r %r %r" % a for a in AERIAL]
    lines += ["aerial_dir %s %r %r %r %r" % (v, *d, dist) for v in ("-", "left", "wall0")
              for d in DIRS for dist in (0, 1.5, 20, 40)]
    lines += ["render %s %d %d %r %r %r %r %d" % r for r in RENDERS]
    want = libsky(probe, daemon.socket, snap.generation, lines)
    assert want is not None, "skyd published another generation meanwhile"
    it = iter(want)
    for e in SKY_EL:
        for a in SKY_AZ:
            agree("libsky sky", snap.sky_radiance(e, a), next(it))
    for e, a in near_sun:
        agree("libsky sky + disks", snap.sky_radiance(e, a, sun_disk=True, moon_disk=True,
                                                      limb_darkening=True), next(it))
    agree("libsky sky + disks", snap.sky_radiance(30, 250, moon_disk=True), next(it))
    agree("libsky sky + disks", snap.sky_radiance(29.5, 251, sun_disk=True, moon_disk=True),
          next(it))
    for alt, mu in TRANS:
        agree("libsky transmittance", snap.transmittance_mu(mu, alt), next(it))
    agree("libsky sun", snap.sun_illuminance(), next(it))
    agree("libsky ambient", snap.ambient_illuminance(), next(it))
    for u, v, d in AERIAL:
        rgb, t = snap.aerial_screen(u, v, d)
        agree("libsky aerial", np.append(rgb, t), next(it))
    for view in (None, "left", "wall0"):
        for d in DIRS:
            for dist in (0, 1.5, 20, 40):
                rgb, t = snap.aerial_dir(d, dist, view=view)
                agree("libsky aerial_dir %s" % (view or "camera"), np.append(rgb, t), next(it))
    for proj, w, h, yaw, pitch, roll, vfov, flags in RENDERS:
        img = snap.render(proj, w, h, yaw, pitch, roll, vfov, sun_disk=bool(flags & 1),
                          moon_disk=bool(flags & 2), limb_darkening=bool(flags & 4))
        ref = np.array([next(it) for _ in range(w * h)], np.float64).reshape(h, w, 3)
        assert img.dtype == np.float32 and img.shape == (h, w, 3)
        agree("libsky render %s" % proj, img, ref)
    assert next(it, None) is None


def test_vectorised_aerial_matches_pointwise(scene):
    _, snap = scene
    u, v, d = np.meshgrid([0, 0.3, 1], [0.05, 0.5], [0, 3, 50], indexing="ij")
    rgb, t = snap.aerial_screen(u, v, d)
    assert rgb.shape == u.shape + (3,) and t.shape == u.shape
    dirs = np.array(DIRS, np.float64)
    for view in (None, "left", "wall0"):
        rgb, t = snap.aerial_dir(dirs, 20.0, view=view)
        for i, d in enumerate(DIRS):
            one = snap.aerial_dir(d, 20.0, view=view)
            assert np.array_equal(rgb[i], one[0]) and t[i] == one[1]
    with pytest.raises(ValueError):
        snap.aerial_dir((0, 0, 0), 1.0)
    with pytest.raises(skyd.TableMissing):
        snap.aerial_dir((0, 1, 0), 1.0, view="nobody")


def test_images(scene):
    _, snap = scene
    fish = snap.fisheye(33)
    assert fish.shape == (33, 33, 3) and fish.dtype == np.float32
    assert (fish[0, 0] == 0).all() and (fish[16, 16] > 0).all()       # corner outside the dome
    # The zenith at the centre of the dome.
    agree("fisheye zenith", fish[16, 16], snap.sky_radiance(90, 0).astype(np.float32))
    eq = snap.equirect(64)
    assert eq.shape == (32, 64, 3)
    # Row 0 looks near the zenith, the last row near the nadir.
    assert eq[0].std(axis=0).max() < 0.05 * eq[0].mean()
    # The centre pixel of an odd-sized camera aimed at the sun: its disk.
    persp = snap.perspective(41, 21, yaw_deg=135, pitch_deg=20, sun_disk=True)
    assert persp.shape == (21, 41, 3)
    assert persp[10, 20].max() > 100 * snap.sky_radiance(20, 135).max()


def test_measured_bound_is_reported():
    """Prints what the comparisons above measured (pytest -s shows it)."""
    for what, e in sorted(MEASURED.items()):
        print("%-28s max relative error %.3g (bound %.3g)" % (what, e, BOUND))
    assert all(e <= BOUND for e in MEASURED.values())
    assert not math.isnan(sum(MEASURED.values()))
