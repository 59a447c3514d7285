"""A consistent copy of one slot: the tables as numpy arrays, the state that
produced them, the views, and sampling and images on them."""

import datetime
import math

import numpy as np

from . import _sample as smp
from ._shm import (CLOUDS_BYTES, FORMAT_RGBA16F, MAX_VIEWS, SLOT_CLOUDS, SLOT_APPLY_TIME_NS, SLOT_BYTES, SLOT_CHECKSUM,
                   SLOT_N_VIEWS, SLOT_STATE, SLOT_VALID_TABLES, SLOT_VALID_VIEWS, SLOT_VIEWS,
                   STATE_BYTES, STATE_DTYPE, TABLE_NAMES, VIEW_BYTES, VIEW_DTYPE, VIEW_PANORAMA,
                   VIEW_VOLUME, CHECKSUM_SEED, checksum_words)


class TableMissing(LookupError):
    """The snapshot holds no valid table of that name (nobody subscribed to
    it when skyd published the slot, or it is still being computed)."""


class State:
    """struct sky_shm_state of a slot: what produced its tables.

    Attributes carry the C names and units (radians, km, lx, ENU unit
    vectors as numpy arrays of 3): utc_unix_s, latitude_rad, longitude_rad
    (NaN when no light is clock-driven), altitude_km, bottom_radius_km,
    top_radius_km, ground_albedo, sun_direction, sun_illuminance_lx,
    sun_angular_radius_rad, moon_direction, moon_illuminance_lx,
    moon_angular_radius_rad, camera_forward, camera_right, camera_up,
    camera_vfov_rad, camera_aspect, aerial_range_km, aerial_squared,
    rgb_scale_log2 (by table id), exposure_ev100 (NaN when none).
    Properties in degrees: sun_elevation_deg, sun_azimuth_deg,
    moon_elevation_deg, moon_azimuth_deg; utc a datetime or None.
    """

    def __init__(self, rec):
        for name in STATE_DTYPE.names:
            v = rec[name]
            if np.ndim(v):
                v = np.array(v, dtype=np.float64 if v.dtype.kind == "f" else np.int64)
                v.flags.writeable = False
            else:
                v = float(v) if isinstance(v, np.floating) else int(v)
            setattr(self, name, v)

    @staticmethod
    def _angles(d):
        return (math.degrees(math.asin(max(-1.0, min(1.0, d[2])))),
                math.degrees(math.atan2(d[0], d[1])) % 360.0)

    @property
    def sun_elevation_deg(self):
        return self._angles(self.sun_direction)[0]

    @property
    def sun_azimuth_deg(self):
        return self._angles(self.sun_direction)[1]

    @property
    def moon_elevation_deg(self):
        return self._angles(self.moon_direction)[0]

    @property
    def moon_azimuth_deg(self):
        return self._angles(self.moon_direction)[1]

    @property
    def utc(self):
        if math.isnan(self.utc_unix_s):
            return None
        return datetime.datetime.fromtimestamp(self.utc_unix_s, datetime.timezone.utc)

    def __repr__(self):
        return "State(sun %.3f deg az %.3f, altitude %.3f km)" % (
            self.sun_elevation_deg, self.sun_azimuth_deg, self.altitude_km)


class View:
    """A camera view of the slot (``view add``): name, index, form ("volume"
    or "panorama"), altitude_km, camera_forward, camera_right, camera_up,
    camera_vfov_rad, camera_aspect, panorama (the struct sky_shm_panorama
    record, form panorama) and array: its aerial perspective, float32
    (depth, height, width, 4): a volume like the aerial table (RGB scaled
    back), or the panorama (RGB the natural log of the radiance)."""

    def __init__(self, index, rec, array):
        self.index = index
        self.name = rec["name"].split(b"\0")[0].decode("ascii", "replace")
        self.form = "panorama" if int(rec["form"]) == VIEW_PANORAMA else "volume"
        self.altitude_km = float(rec["altitude_km"])
        self.camera_forward = np.array(rec["camera_forward"], dtype=np.float64)
        self.camera_right = np.array(rec["camera_right"], dtype=np.float64)
        self.camera_up = np.array(rec["camera_up"], dtype=np.float64)
        self.camera_vfov_rad = float(rec["camera_vfov_rad"])
        self.camera_aspect = float(rec["camera_aspect"])
        self.panorama = rec["panorama"].copy() if self.form == "panorama" else None
        self.array = array

    def __repr__(self):
        return "View(%r, %s, %s)" % (self.name, self.form, self.array.shape)


def _table_array(data, info, scale_log2):
    """A table's texels as float32 (shape info.shape), half floats widened
    and their RGB scaled by 2^scale_log2 (exact: a power of two)."""
    n = info.width * info.height * info.depth * 4
    if info.format_id == FORMAT_RGBA16F:
        a = np.frombuffer(data, np.float16, count=n, offset=info.offset).astype(np.float32)
        a = a.reshape(info.shape)
        if scale_log2:
            a[..., :3] = np.ldexp(a[..., :3], np.int32(scale_log2))
        a.flags.writeable = False
        return a
    return np.frombuffer(data, np.float32, count=n, offset=info.offset).reshape(info.shape)


def _deg(x):
    return np.asarray(x, dtype=np.float64) * smp.DEG


class Snapshot:
    """One slot of skyd's shared memory, copied under its seqlock.

    generation        the slot's generation (what set and sample name)
    slot_index        which slot it was copied from
    retries           copies thrown away because skyd rewrote the slot
    apply_time_ns     CLOCK_REALTIME at which the slot became current (0: at once)
    apply_time        the same as a datetime, or None for 0
    state             State: the sun, moon, planet and camera of the tables
    valid             names of the tables valid in the slot
    transmittance, multiscatter, skyview, aerial
                      the tables as float32 arrays: (height, width, 4), the
                      aerial volume (depth, height, width, 4); rows bottom-up
                      in v (proto/skymap.h); TableMissing when not valid
    tables            {name: array} of the valid tables
    views             {name: View} of the valid views
    layout            {name: TableInfo} of the region

    Sampling (float64, vectorised: arrays broadcast, trailing axis RGB):
    sky_radiance, transmittance_mu, sky_transmittance, aerial_screen,
    aerial_dir, sun_illuminance, ambient_illuminance; images: fisheye,
    equirect, perspective.
    """

    def __init__(self, region, data, slot_index, generation, retries):
        self.raw = data
        self.slot_index = slot_index
        self.generation = int(generation)
        self.retries = retries
        self.layout = region.tables
        self._view_offset, self._view_stride = region.view_offset, region.view_stride
        self._max_views = region.max_views
        self._slot_bytes = region.slot_bytes
        self.apply_time_ns = int(np.frombuffer(data, "=i8", 1, SLOT_APPLY_TIME_NS)[0])
        self.checksum = int(np.frombuffer(data, "=u8", 1, SLOT_CHECKSUM)[0])
        self._valid_bits = int(np.frombuffer(data, "=u4", 1, SLOT_VALID_TABLES)[0])
        self.state = State(np.frombuffer(data, STATE_DTYPE, 1, SLOT_STATE)[0])
        self.valid = tuple(n for n in TABLE_NAMES
                           if self._valid_bits & (1 << TABLE_NAMES.index(n)) and n in self.layout)
        self._arrays = {}
        self._views = None

    @property
    def apply_time(self):
        if not self.apply_time_ns:
            return None
        return datetime.datetime.fromtimestamp(self.apply_time_ns / 1e9, datetime.timezone.utc)

    def table(self, name):
        """The named table's array; TableMissing when it is not valid."""
        if name not in self._arrays:
            if name not in self.valid:
                raise TableMissing("no valid %s table in generation %d (valid: %s)"
                                   % (name, self.generation, ", ".join(self.valid) or "none"))
            info = self.layout[name]
            self._arrays[name] = _table_array(self.raw, info, self.state.rgb_scale_log2[info.id])
        return self._arrays[name]

    transmittance = property(lambda self: self.table("transmittance"))
    multiscatter = property(lambda self: self.table("multiscatter"))
    skyview = property(lambda self: self.table("skyview"))
    aerial = property(lambda self: self.table("aerial"))

    @property
    def tables(self):
        return {n: self.table(n) for n in self.valid}

    @property
    def views(self):
        if self._views is None:
            self._views = self._read_views()
        return self._views

    def _read_views(self):
        data = self.raw
        n = int(np.frombuffer(data, "=u4", 1, SLOT_N_VIEWS)[0])
        valid = int(np.frombuffer(data, "=u4", 1, SLOT_VALID_VIEWS)[0])
        if not n or n > MAX_VIEWS:
            return {}
        recs = np.frombuffer(data, VIEW_DTYPE, n, SLOT_VIEWS)
        out = {}
        for i in range(min(n, self._max_views)):
            if not valid & (1 << i):
                continue
            rec = recs[i]
            if int(rec["form"]) == VIEW_PANORAMA:
                arr = self._panorama_array(rec["panorama"])
            elif int(rec["form"]) == VIEW_VOLUME and "aerial" in self.layout:
                info = self.layout["aerial"]
                shifted = _Shifted(info, self._view_offset + i * self._view_stride)
                arr = _table_array(data, shifted, self.state.rgb_scale_log2[info.id])
            else:
                continue
            v = View(i, rec, arr)
            out[v.name] = v
        return out

    def _panorama_array(self, p):
        w, h, d = int(p["width"]), int(p["height"]), int(p["depth"])
        off, nbytes = int(p["offset"]), int(p["bytes"])
        # skysample_check_panorama: the entry comes from a peer.
        if (not w or not h or not d or max(w, h, d) > 65536 or nbytes != w * h * d * 16
                or off % 8 or off < SLOT_BYTES or off > self._slot_bytes
                or nbytes > self._slot_bytes - off):
            raise ValueError("a view's panorama lies outside its slot")
        return np.frombuffer(self.raw, np.float32, w * h * d * 4, off).reshape(d, h, w, 4)

    def verify(self):
        """True when the slot's checksum (FNV-1a over the state, the valid
        tables and the views, PROTOCOL.md "Checksum") matches the copy. A
        pass over every byte in Python: about 50 ms per MB."""
        h = checksum_words(CHECKSUM_SEED, self.raw, SLOT_STATE, STATE_BYTES)
        h = checksum_words(h, self.raw, SLOT_CLOUDS, CLOUDS_BYTES)
        for tid, name in enumerate(TABLE_NAMES):
            if self._valid_bits & (1 << tid) and name in self.layout:
                info = self.layout[name]
                h = checksum_words(h, self.raw, info.offset, info.bytes)
        n = int(np.frombuffer(self.raw, "=u4", 1, SLOT_N_VIEWS)[0])
        if not n or n > MAX_VIEWS:
            return h == self.checksum
        h = checksum_words(h, self.raw, SLOT_VIEWS, n * VIEW_BYTES)
        valid = int(np.frombuffer(self.raw, "=u4", 1, SLOT_VALID_VIEWS)[0])
        recs = np.frombuffer(self.raw, VIEW_DTYPE, n, SLOT_VIEWS)
        for i in range(min(n, self._max_views)):
            if not valid & (1 << i):
                continue
            if int(recs[i]["form"]) == VIEW_PANORAMA:
                p = recs[i]["panorama"]
                try:
                    self._panorama_array(p)
                except ValueError:
                    continue
                h = checksum_words(h, self.raw, int(p["offset"]), int(p["bytes"]))
            elif int(recs[i]["form"]) == VIEW_VOLUME and "aerial" in self.layout:
                h = checksum_words(h, self.raw, self._view_offset + i * self._view_stride,
                                   self.layout["aerial"].bytes)
        return h == self.checksum

    # Sampling ----------------------------------------------------------

    def sky_radiance(self, el_deg, az_deg, sun_disk=False, moon_disk=False,
                     limb_darkening=False):
        """Sky radiance (..., 3), cd/m2 per channel, toward elevation el_deg
        above the horizon and azimuth az_deg east of north: the sky-view
        table as libsky's sky_sample_sky and skyd's ``sample sky`` read it,
        without the disks unless asked (those need the transmittance)."""
        el, az = _deg(el_deg), _deg(az_deg)
        rgb = smp.sky(self.skyview, self.state, el, az)
        return self._disks(rgb, smp.direction(el, az), sun_disk, moon_disk, limb_darkening)

    def _disks(self, rgb, dirs, sun_disk, moon_disk, limb_darkening):
        st = self.state
        if sun_disk:
            rgb = smp.add_disk(self.transmittance, st, st.sun_direction, st.sun_illuminance_lx,
                               st.sun_angular_radius_rad, dirs,
                               smp.LIMB_U if limb_darkening else 0.0, rgb)
        if moon_disk:
            rgb = smp.add_disk(self.transmittance, st, st.moon_direction, st.moon_illuminance_lx,
                               st.moon_angular_radius_rad, dirs, 0.0, rgb)
        return rgb

    def transmittance_mu(self, mu, altitude_km=None):
        """Transmittance (..., 3) from altitude_km (default: the observer's)
        to the top of the atmosphere along the zenith cosine mu, for rays
        that miss the ground (skysample_transmittance)."""
        alt = self.state.altitude_km if altitude_km is None else altitude_km
        return smp.transmittance(self.transmittance, self.state, alt, mu)

    def sky_transmittance(self, el_deg, az_deg=0.0):
        """Transmittance (..., 3) from the observer toward elevation el_deg to
        the top of the atmosphere, 0 where the ray meets the ground: what
        a light in that direction is dimmed by."""
        return smp.light_transmittance(self.transmittance, self.state,
                                       smp.direction(_deg(el_deg), _deg(az_deg)))

    def sun_illuminance(self):
        """The sun's illuminance at the observer on a surface facing it (3,),
        lx per channel: ``sample sun``."""
        return smp.sun(self.transmittance, self.state)

    def ambient_illuminance(self):
        """Horizontal irradiance from the sky, no sun (3,), lx per channel:
        ``sample ambient``."""
        return smp.ambient(self.skyview, self.state)

    def _aerial_source(self, view):
        st = self.state
        if view is None:
            return (self.aerial, None, st.camera_forward, st.camera_right, st.camera_up,
                    st.camera_vfov_rad, st.camera_aspect)
        try:
            v = self.views[view]
        except KeyError:
            raise TableMissing("no valid view %r in generation %d" % (view, self.generation)) \
                from None
        return (v.array, v.panorama, v.camera_forward, v.camera_right, v.camera_up,
                v.camera_vfov_rad, v.camera_aspect)

    def aerial_screen(self, screen_u, screen_v, distance_km, view=None):
        """Aerial perspective at screen positions (u right, v up, [0, 1]) of
        the state's camera (view None) or a view's, distance_km along the
        ray: (in-scattered rgb (..., 3) cd/m2, transmittance (...)). Apply
        as L = L_surface * T + rgb. A panorama view is read toward the
        direction through that screen position."""
        tex, pano, f, r, u, vfov, aspect = self._aerial_source(view)
        if pano is None:
            return smp.aerial(tex, self.state, screen_u, screen_v, distance_km)
        x = (2.0 * np.asarray(screen_u, np.float64) - 1.0) * math.tan(0.5 * vfov) * aspect
        y = (2.0 * np.asarray(screen_v, np.float64) - 1.0) * math.tan(0.5 * vfov)
        x, y = np.broadcast_arrays(x, y)
        d = f + x[..., None] * r + y[..., None] * u
        d = d / np.sqrt((d * d).sum(axis=-1))[..., None]
        return smp.panorama(tex, pano, self.state, d, distance_km)

    def aerial_dir(self, directions, distance_km, view=None):
        """Aerial perspective toward ENU directions (..., 3) (any length but
        0), distance_km along them, for the state's camera (view None) or a
        view: sky_sample_view_aerial_dir(). (rgb (..., 3), transmittance (...))."""
        d = np.asarray(directions, dtype=np.float64)
        n = np.sqrt(d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1] + d[..., 2] * d[..., 2])
        if not np.all(np.isfinite(n) & (n > 0.0)):
            raise ValueError("a direction of zero or non-finite length")
        d = d / n[..., None]
        tex, pano, f, r, u, vfov, aspect = self._aerial_source(view)
        if pano is not None:
            return smp.panorama(tex, pano, self.state, d, distance_km)
        su, sv = smp.screen_uv(f, r, u, math.tan(0.5 * vfov), aspect, d)
        return smp.aerial(tex, self.state, su, sv, distance_km)

    # Images ------------------------------------------------------------

    def render(self, projection, width, height, yaw_deg=0.0, pitch_deg=0.0, roll_deg=0.0,
               vfov_deg=60.0, sun_disk=False, moon_disk=False, limb_darkening=False):
        """The sky as libsky's sky_render draws it: float32 (height, width, 3)
        linear RGB radiance (cd/m2), rows top to bottom; black outside a
        fisheye's circle. projection: "fisheye", "equirect", "perspective"."""
        dirs, shown = smp.render_directions(projection, width, height, yaw_deg, pitch_deg,
                                            roll_deg, vfov_deg)
        el = np.arcsin(smp.clamp(dirs[..., 2], -1.0, 1.0))
        az = np.arctan2(dirs[..., 0], dirs[..., 1])
        rgb = smp.sky(self.skyview, self.state, el, az)
        rgb = self._disks(rgb, dirs, sun_disk, moon_disk, limb_darkening)
        rgb = np.where(shown[..., None], rgb, 0.0)
        return rgb.astype(np.float32)

    def fisheye(self, size, yaw_deg=0.0, **disks):
        """A planetarium dome master, size x size: zenith at the centre, the
        horizon on the circle, azimuth yaw_deg at the bottom."""
        return self.render("fisheye", size, size, yaw_deg=yaw_deg, **disks)

    def equirect(self, width, height=None, **disks):
        """Equirectangular: azimuth 0 (north) at the left edge, eastward;
        elevation +90 at the top to -90 at the bottom."""
        return self.render("equirect", width, height or max(1, width // 2), **disks)

    def perspective(self, width, height, yaw_deg=180.0, pitch_deg=0.0, roll_deg=0.0,
                    vfov_deg=60.0, **disks):
        """A pinhole camera looking at (yaw_deg, pitch_deg)."""
        return self.render("perspective", width, height, yaw_deg, pitch_deg, roll_deg, vfov_deg,
                           **disks)

    def __repr__(self):
        return "Snapshot(generation %d, %s)" % (self.generation, ", ".join(
            "%s %s" % (n, "x".join(map(str, self.layout[n].shape))) for n in self.valid))


class _Shifted:
    """A TableInfo moved to another offset: a view's volume."""

    def __init__(self, info, offset):
        self.__dict__.update(info.__dict__)
        self.offset = offset

    @property
    def shape(self):
        return (self.depth, self.height, self.width, 4)


def direction(el_deg, az_deg):
    """Unit east-north-up vectors (..., 3) of elevations and azimuths in degrees."""
    return smp.direction(_deg(el_deg), _deg(az_deg))
