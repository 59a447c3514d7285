"""The mappings of proto/skymap.h and the sampling of proto/skysample.h,
vectorised over numpy arrays of directions and distances.

Every function computes in float64 with the operations of the C code in its
order, so that a table read through this module gives the numbers libsky
and skyd's ``sample`` verb give, to the last bits of float64 (the tests
measure it). Tables are float32 arrays of shape (depth, height, width, 4),
RGB already scaled (skyd's half floats times 2^rgb_scale_log2: exact).
Angles in radians, lengths in km, directions east-north-up unit vectors.
"""

import numpy as np

PI = 3.14159265358979323846
DEG = PI / 180.0
LIMB_U = 0.6                  # libsky's linear limb darkening (sky_render.c)
AMBIENT_EL = 64               # skysample_ambient's quadrature
AMBIENT_AZ = 128
REC709 = (0.2126, 0.7152, 0.0722)


def clamp(x, lo, hi):
    # x < lo ? lo : x > hi ? hi : x, NaN passing through as in C.
    x = np.asarray(x, dtype=np.float64)
    return np.where(x < lo, lo, np.where(x > hi, hi, x))


def safe_sqrt(x):
    x = np.asarray(x, dtype=np.float64)
    return np.sqrt(np.where(x > 0.0, x, 0.0))


def unit_to_tex(x, n):
    return 0.5 / n + x * (1.0 - 1.0 / n)


def rho2(rb, altitude_km):
    return altitude_km * (2.0 * rb + altitude_km)


def horizon_cos(rb, altitude_km):
    h = np.where(np.asarray(altitude_km) > 0.0, altitude_km, 0.0)
    return -safe_sqrt(rho2(rb, h)) / (rb + h)


def distance_to_top(rb, rt, altitude_km, mu):
    r = rb + altitude_km
    big_h2 = (rt - rb) * (rt + rb)
    disc = r * r * mu * mu + big_h2 - rho2(rb, altitude_km)
    d = -r * mu + safe_sqrt(disc)
    return np.where(d > 0.0, d, 0.0)


def transmittance_uv(rb, rt, altitude_km, mu, w, h):
    alt = clamp(altitude_km, 0.0, rt - rb)
    big_h = safe_sqrt((rt - rb) * (rt + rb))
    rho = safe_sqrt(rho2(rb, alt))
    d = distance_to_top(rb, rt, alt, clamp(mu, -1.0, 1.0))
    d_min, d_max = (rt - rb) - alt, rho + big_h
    with np.errstate(divide="ignore", invalid="ignore"):
        x_mu = np.where(d_max > d_min, (d - d_min) / (d_max - d_min), 0.0)
    u = unit_to_tex(clamp(x_mu, 0.0, 1.0), w)
    v = unit_to_tex(clamp(rho / big_h, 0.0, 1.0), h)
    return u, v


def skyview_uv(hc, view_zenith_rad, azimuth_rad, h):
    th = np.arccos(clamp(hc, -1.0, 1.0))
    t = clamp(view_zenith_rad, 0.0, PI)
    with np.errstate(divide="ignore", invalid="ignore"):
        x = np.where(t < th, 0.5 * (1.0 - safe_sqrt(1.0 - t / th)),
                     0.5 + 0.5 * safe_sqrt((t - th) / (PI - th)))
    a = np.asarray(azimuth_rad, dtype=np.float64) / (2.0 * PI)
    return a - np.floor(a), unit_to_tex(x, h)


def aerial_depth_km(k, n, range_km, squared):
    x = (np.asarray(k, dtype=np.float64) + 1) / n
    return range_km * (x * x if squared else x)


def aerial_slice(depth_km, n, range_km, squared):
    x = clamp(np.asarray(depth_km, dtype=np.float64) / range_km, 0.0, 1.0)
    return (np.sqrt(x) if squared else x) * n - 1.0


def panorama_uv(p, width, height, azimuth_rad, elevation_rad):
    """skymap_panorama_uv with p a struct sky_shm_panorama record."""
    two_pi = 2.0 * PI
    az0, step = float(p["azimuth0_rad"]), float(p["azimuth_step_rad"])
    du = np.asarray(azimuth_rad, dtype=np.float64) - az0
    du = du - two_pi * np.floor(du / two_pi)
    if not int(p["full_circle"]):
        span = step * (width - 1.0)
        du = np.where(du > span, np.where(du - span < two_pi - du, span, 0.0), du)
    f = clamp(du / step, 0.0, width - 1.0)
    e = np.asarray(elevation_rad, dtype=np.float64) - float(p["horizon_rad"])
    x = np.where(e < 0.0, -np.sqrt(np.abs(e)), np.sqrt(np.abs(e)))
    g = clamp((x - float(p["row0"])) / float(p["row_step"]), 0.0, height - 1.0)
    return (f + 0.5) / width, (g + 0.5) / height


def _axis(u, n, wrap):
    """skysample_axis: two texel indices and the weight of the second."""
    x = np.asarray(u, dtype=np.float64) * n - 0.5
    x = np.where(np.isnan(x), 0.0, x)
    with np.errstate(invalid="ignore"):
        fl = np.floor(x)
        f = x - fl
    if wrap:
        with np.errstate(invalid="ignore"):
            m = np.fmod(fl, float(n))
        m = np.where(m < 0.0, m + n, m)
        ok = (m >= 0.0) & (m < n)
        i0 = np.where(ok, m, 0.0).astype(np.int64)
        i1 = np.where(i0 + 1 < n, i0 + 1, 0)
        return i0, i1, f
    lo, hi = fl < 0.0, fl >= n - 1
    i0 = np.where(lo, 0.0, np.where(hi, n - 1.0, fl)).astype(np.int64)
    i1 = np.where(lo, 0, np.where(hi, n - 1, i0 + 1))
    return i0, i1, np.where(lo | hi, 0.0, f)


def bilinear(tex, u, v, k, wrap_u):
    """skysample_bilinear of slice k (an index or an array of them) at
    (u, v): RGBA as float64, shape (..., 4)."""
    depth, height, width, _ = tex.shape
    i0, i1, fu = _axis(u, width, wrap_u)
    j0, j1, fv = _axis(v, height, False)
    k = np.broadcast_to(np.asarray(k, dtype=np.int64), np.broadcast(i0, j0).shape)
    a = tex[k, j0, i0].astype(np.float64)
    b = tex[k, j0, i1].astype(np.float64)
    c = tex[k, j1, i0].astype(np.float64)
    d = tex[k, j1, i1].astype(np.float64)
    fu = np.asarray(fu)[..., None]
    fv = np.asarray(fv)[..., None]
    lo = a + fu * (b - a)
    hi = c + fu * (d - c)
    return lo + fv * (hi - lo)


def as_volume(table):
    """A (height, width, 4) table as (1, height, width, 4); volumes as they are."""
    return table[None] if table.ndim == 3 else table


def transmittance(tex, st, altitude_km, mu):
    """skysample_transmittance: (..., 3) in [0, 1]."""
    tex = as_volume(tex)
    u, v = transmittance_uv(st.bottom_radius_km, st.top_radius_km, altitude_km, mu,
                            tex.shape[2], tex.shape[1])
    return bilinear(tex, u, v, 0, False)[..., :3]


def sky(tex, st, elevation_rad, azimuth_rad):
    """skysample_sky: radiance (..., 3) toward (elevation, azimuth)."""
    tex = as_volume(tex)
    hc = horizon_cos(st.bottom_radius_km, st.altitude_km)
    u, v = skyview_uv(hc, 0.5 * PI - np.asarray(elevation_rad, dtype=np.float64), azimuth_rad,
                      tex.shape[1])
    return bilinear(tex, u, v, 0, True)[..., :3]


def aerial(tex, st, screen_u, screen_v, distance_km):
    """skysample_aerial: (rgb (..., 3), transmittance (...))."""
    depth = tex.shape[0]
    w = aerial_slice(distance_km, depth, st.aerial_range_km, st.aerial_squared != 0)
    w = np.where(np.isnan(w), -1.0, w)
    su, sv = np.broadcast_arrays(np.asarray(screen_u, np.float64), np.asarray(screen_v, np.float64))
    w, su, sv = np.broadcast_arrays(w, su, sv)
    near, far = w <= 0.0, (w > 0.0) & (w >= depth - 1)
    mid = ~(near | far)
    k = np.floor(np.where(mid, w, 0.0)).astype(np.int64)
    a = bilinear(tex, su, sv, np.where(near, 0, np.where(far, depth - 1, k + 1)), False)
    b = np.where(mid[..., None], bilinear(tex, su, sv, k, False), np.array([0.0, 0.0, 0.0, 1.0]))
    f = np.where(near, np.maximum(w + 1.0, 0.0), np.where(far, 1.0, w - k))[..., None]
    out = b + f * (a - b)
    return out[..., :3], out[..., 3]


def direction(elevation_rad, azimuth_rad):
    """skysample_direction: unit ENU vectors (..., 3)."""
    el = np.asarray(elevation_rad, dtype=np.float64)
    az = np.asarray(azimuth_rad, dtype=np.float64)
    return np.stack(np.broadcast_arrays(np.cos(el) * np.sin(az), np.cos(el) * np.cos(az),
                                        np.sin(el)), axis=-1)


def screen_uv(fwd, right, up, tan_half_vfov, aspect, dirs):
    """skysample_screen_uv: where unit directions land on a camera's screen."""
    d = np.asarray(dirs, dtype=np.float64)
    z = d[..., 0] * fwd[0] + d[..., 1] * fwd[1] + d[..., 2] * fwd[2]
    x = d[..., 0] * right[0] + d[..., 1] * right[1] + d[..., 2] * right[2]
    y = d[..., 0] * up[0] + d[..., 1] * up[1] + d[..., 2] * up[2]
    z = np.where(z > 1e-6, z, 1e-6)
    return 0.5 + 0.5 * x / (tan_half_vfov * aspect) / z, 0.5 + 0.5 * y / tan_half_vfov / z


def panorama(tex, p, st, dirs, distance_km):
    """skysample_panorama: (rgb (..., 3), transmittance (...)) toward unit
    directions dirs from a panorama whose RGB is the log of the radiance."""
    depth, height, width, _ = tex.shape
    d = np.asarray(dirs, dtype=np.float64)
    w = aerial_slice(distance_km, depth, st.aerial_range_km, st.aerial_squared != 0)
    w = np.where(np.isnan(w), -1.0, w)
    u, v = panorama_uv(p, width, height, np.arctan2(d[..., 0], d[..., 1]),
                       np.arcsin(clamp(d[..., 2], -1.0, 1.0)))
    w, u, v = np.broadcast_arrays(w, u, v)
    wc = clamp(w, 0.0, depth - 1.0)
    k = np.floor(wc).astype(np.int64)
    k1 = np.where(k + 1 < depth, k + 1, k)
    f = (wc - k)[..., None]
    a = bilinear(tex, u, v, k, False)
    b = bilinear(tex, u, v, k1, False)
    m = np.where(w < 0.0, np.where(w + 1.0 > 0.0, w + 1.0, 0.0), 1.0)
    lin = a + f * (b - a)
    rgb = m[..., None] * np.exp(lin[..., :3])
    return rgb, 1.0 + m * (lin[..., 3] - 1.0)


def light_transmittance(tex, st, dirs):
    """skysample_light_transmittance: 0 where the direction meets the ground."""
    d = np.asarray(dirs, dtype=np.float64)
    mu = d[..., 2]
    t = transmittance(tex, st, st.altitude_km, mu)
    ground = mu < horizon_cos(st.bottom_radius_km, st.altitude_km)
    return np.where(ground[..., None], 0.0, t)


def sun(tex, st):
    """skysample_sun: the sun's illuminance at the observer (3,), lx."""
    return np.asarray(st.sun_illuminance_lx) * light_transmittance(tex, st, st.sun_direction)


def ambient(tex, st):
    """skysample_ambient: the horizontal sky irradiance (3,), lx, by the
    same 64 x 128 midpoint quadrature (the sums in another order: equal to
    float64 rounding)."""
    dth = 0.5 * PI / AMBIENT_EL
    th = (np.arange(AMBIENT_EL) + 0.5) * dth
    az = (np.arange(AMBIENT_AZ) + 0.5) * (2.0 * PI / AMBIENT_AZ)
    w = np.cos(th) * np.sin(th)
    rgb = sky(tex, st, (0.5 * PI - th)[:, None], az[None, :])
    ring = rgb.sum(axis=1)
    total = (w[:, None] * ring).sum(axis=0)
    wsum = (w * AMBIENT_AZ).sum()
    return PI * total / wsum


def add_disk(trans, st, light_dir, illuminance_lx, angular_radius_rad, views, limb_u, rgb):
    """skysample_add_disk over arrays of view directions; adds into rgb."""
    if not angular_radius_rad > 0.0:
        return rgb
    ld = np.asarray(light_dir, dtype=np.float64)
    v = np.asarray(views, dtype=np.float64)
    d = v[..., 0] * ld[0] + v[..., 1] * ld[1] + v[..., 2] * ld[2]
    inside = d >= np.cos(angular_radius_rad)
    if not inside.any():
        return rgb
    tr = light_transmittance(trans, st, ld)
    solid = PI * angular_radius_rad * angular_radius_rad
    limb = np.ones_like(d)
    if limb_u > 0.0:
        s = safe_sqrt(1.0 - d * d) / np.sin(angular_radius_rad)
        m = safe_sqrt(1.0 - np.where(s > 1.0, 1.0, s * s))
        limb = (1.0 - limb_u * (1.0 - m)) / (1.0 - limb_u / 3.0)
    add = np.asarray(illuminance_lx) / solid * tr * limb[..., None]
    return rgb + np.where(inside[..., None], add, 0.0)


def camera_basis(yaw_deg, pitch_deg, roll_deg):
    """sky_render.c's perspective camera: forward, right, up."""
    yaw, pitch, roll = yaw_deg * DEG, pitch_deg * DEG, roll_deg * DEG
    f = direction(pitch, yaw)
    r0 = np.array([np.cos(yaw), -np.sin(yaw), 0.0])
    u0 = np.array([r0[1] * f[2] - r0[2] * f[1], r0[2] * f[0] - r0[0] * f[2],
                   r0[0] * f[1] - r0[1] * f[0]])
    r = np.cos(roll) * r0 + np.sin(roll) * u0
    u = np.cos(roll) * u0 - np.sin(roll) * r0
    return f, r, u


def render_directions(projection, width, height, yaw_deg=0.0, pitch_deg=0.0, roll_deg=0.0,
                      vfov_deg=60.0):
    """sky_render_direction for every pixel centre: (dirs (h, w, 3), shown
    (h, w) bool). Projections as enum sky_projection: "equirect" (north at
    the left, zenith at the top), "fisheye" (a dome master: zenith at the
    centre, azimuth yaw_deg at the bottom) and "perspective"."""
    x = np.arange(width, dtype=np.float64)[None, :] + 0.5
    y = np.arange(height, dtype=np.float64)[:, None] + 0.5
    w, h = float(width), float(height)
    if projection == "equirect":
        dirs = direction(0.5 * PI - PI * y / h, 2.0 * PI * x / w)
        return dirs, np.ones((height, width), bool)
    if projection == "fisheye":
        rad = 0.5 * min(w, h)
        dx, dy = (x - 0.5 * w) / rad, (0.5 * h - y) / rad
        rho = np.sqrt(dx * dx + dy * dy)
        az = yaw_deg * DEG + np.arctan2(dx, -dy)
        return direction(0.5 * PI * (1.0 - rho), az), np.broadcast_to(rho <= 1.0, az.shape)
    if projection == "perspective":
        if not 0.0 < vfov_deg < 180.0:
            raise ValueError("vfov_deg %r is outside (0, 180)" % vfov_deg)
        f, r, u = camera_basis(yaw_deg, pitch_deg, roll_deg)
        t = np.tan(0.5 * vfov_deg * DEG)
        sx = (2.0 * (x / w) - 1.0) * t * (w / h)
        sy = (2.0 * (1.0 - y / h) - 1.0) * t
        sx, sy = np.broadcast_arrays(sx, sy)
        d = f + sx[..., None] * r + sy[..., None] * u
        n = np.sqrt(d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1] + d[..., 2] * d[..., 2])
        return d / n[..., None], np.ones((height, width), bool)
    raise ValueError("%r: not equirect, fisheye or perspective" % (projection,))
