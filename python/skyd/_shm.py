"""The shared memory: the sealed memfd mapped read-only, its header checked,
seqlock snapshots of the newest slot, and the futex wait on its generation.

The layout is proto/skyproto.h's (layout 8, uv mapping 4): the offsets below
are those of its structs on every Linux ABI skyd runs on (natural alignment,
no packing); the tests compare them with the C compiler's offsetof.
"""

import ctypes
import errno
import fcntl
import mmap
import os
import platform
import struct
import threading
import time

import numpy as np

from ._wire import ProtocolError

MAGIC = 0x31594B53            # "SKY1" little-endian
LAYOUT_VERSION = 8
UV_MAPPING_VERSION = 4        # SKYMAP_VERSION
MAX_TABLES = 6
MIN_SLOTS = 3
MAX_VIEWS = 8
VIEW_NAME_MAX = 32
TABLE_NAMES = ("transmittance", "multiscatter", "skyview", "aerial", "cloud", "shadow")
# What "all" names: the sky's four tables; the cloud tables (layout 7)
# exist only while a cloud layer is drawn and are asked for by name.
SKY_TABLE_NAMES = TABLE_NAMES[:4]
FORMAT_RGBA32F = 1
FORMAT_RGBA16F = 2
VIEW_VOLUME = 0
VIEW_PANORAMA = 1
SNAPSHOT_TRIES = 16           # as libsky's sky_snapshot
CHECKSUM_SEED = 0xCBF29CE484222325
CHECKSUM_PRIME = 0x100000001B3

# struct sky_shm_header: the words a reader polls, and its size.
HDR_GENERATION = 40
HDR_CURRENT_SLOT = 44
HDR_SUPERSEDED = 48
HDR_TABLES = 56
HDR_BYTES = 320
# struct sky_shm_slot.
SLOT_SEQ = 0
SLOT_VALID_TABLES = 4
SLOT_GENERATION = 8
SLOT_APPLY_TIME_NS = 16
SLOT_CHECKSUM = 24
SLOT_STATE = 32
SLOT_N_VIEWS = 448
SLOT_VALID_VIEWS = 452
SLOT_VIEWS = 456
SLOT_CLOUDS = 2120
SLOT_BYTES = 2712
CLOUDS_BYTES = 592
STATE_BYTES = 416
VIEW_BYTES = 208


def _dtype(fields, itemsize):
    names, formats, offsets = zip(*fields)
    return np.dtype({"names": list(names), "formats": list(formats),
                     "offsets": list(offsets), "itemsize": itemsize})


V3 = ("=f8", (3,))
STATE_DTYPE = _dtype([
    ("utc_unix_s", "=f8", 0), ("latitude_rad", "=f8", 8), ("longitude_rad", "=f8", 16),
    ("altitude_km", "=f8", 24), ("bottom_radius_km", "=f8", 32), ("top_radius_km", "=f8", 40),
    ("ground_albedo", V3, 48), ("sun_direction", V3, 72), ("sun_illuminance_lx", V3, 96),
    ("sun_angular_radius_rad", "=f8", 120), ("moon_direction", V3, 128),
    ("moon_illuminance_lx", V3, 152), ("moon_angular_radius_rad", "=f8", 176),
    ("camera_forward", V3, 184), ("camera_right", V3, 208), ("camera_up", V3, 232),
    ("camera_vfov_rad", "=f8", 256), ("camera_aspect", "=f8", 264),
    ("aerial_range_km", "=f8", 272), ("aerial_squared", "=u4", 280),
    ("rgb_scale_log2", ("=i4", (MAX_TABLES,)), 288), ("exposure_ev100", "=f8", 312)],
    STATE_BYTES)
PANORAMA_DTYPE = _dtype([
    ("offset", "=u8", 0), ("bytes", "=u8", 8), ("width", "=u4", 16), ("height", "=u4", 20),
    ("depth", "=u4", 24), ("full_circle", "=u4", 28), ("azimuth0_rad", "=f8", 32),
    ("azimuth_step_rad", "=f8", 40), ("row0", "=f8", 48), ("row_step", "=f8", 56),
    ("horizon_rad", "=f8", 64)], 72)
VIEW_DTYPE = _dtype([
    ("name", "S%d" % VIEW_NAME_MAX, 0), ("altitude_km", "=f8", 32),
    ("camera_forward", V3, 40), ("camera_right", V3, 64), ("camera_up", V3, 88),
    ("camera_vfov_rad", "=f8", 112),
    ("camera_aspect", "=f8", 120), ("form", "=u4", 128), ("panorama", PANORAMA_DTYPE, 136)],
    VIEW_BYTES)
TABLE_DTYPE = _dtype([("id", "=u4", 0), ("format", "=u4", 4), ("width", "=u4", 8),
                      ("height", "=u4", 12), ("depth", "=u4", 16), ("texel_bytes", "=u4", 20),
                      ("offset", "=u8", 24), ("bytes", "=u8", 32)], 40)
HEADER_DTYPE = _dtype([
    ("magic", "=u4", 0), ("layout_version", "=u4", 4), ("uv_mapping_version", "=u4", 8),
    ("header_bytes", "=u4", 12), ("n_slots", "=u4", 16), ("n_tables", "=u4", 20),
    ("slot_bytes", "=u8", 24), ("total_bytes", "=u8", 32), ("generation", "=u4", 40),
    ("current_slot", "=u4", 44), ("superseded", "=u4", 48),
    ("tables", (TABLE_DTYPE, (MAX_TABLES,)), 56), ("max_views", "=u4", 296),
    ("view_offset", "=u8", 304), ("view_stride", "=u8", 312)], HDR_BYTES)


class LayoutError(ProtocolError):
    """The shared memory is not a layout this package reads: another layout
    or uv-mapping version (upgrade the package to match skyd), or a header
    that fails its checks."""


class TornReadError(RuntimeError):
    """skyd rewrote the slot during every one of SNAPSHOT_TRIES copies."""


class TableInfo:
    """One table of the layout: name, id, format ("rgba32f" or "rgba16f"),
    width, height, depth, texel_bytes, offset (from a slot's start), bytes;
    shape is the numpy shape of its array: (height, width, 4), or
    (depth, height, width, 4) for the aerial volume."""

    def __init__(self, rec):
        self.id = int(rec["id"])
        self.name = TABLE_NAMES[self.id]
        self.format_id = int(rec["format"])
        self.format = "rgba16f" if self.format_id == FORMAT_RGBA16F else "rgba32f"
        self.width, self.height = int(rec["width"]), int(rec["height"])
        self.depth = int(rec["depth"])
        self.texel_bytes = int(rec["texel_bytes"])
        self.offset = int(rec["offset"])
        self.bytes = int(rec["bytes"])

    @property
    def shape(self):
        if self.id == 3 or self.depth > 1:
            return (self.depth, self.height, self.width, 4)
        return (self.height, self.width, 4)

    def __repr__(self):
        return "TableInfo(%s %s %dx%dx%d at %d)" % (self.name, self.format, self.width,
                                                    self.height, self.depth, self.offset)


def check_header(h, map_bytes):
    """skysample_check_layout in Python: raises LayoutError unless the header
    (a HEADER_DTYPE record) describes a region this package can index."""
    if map_bytes < HDR_BYTES or int(h["magic"]) != MAGIC:
        raise LayoutError("not skyd's shared memory (magic %#x)" % int(h["magic"]))
    lv, uv = int(h["layout_version"]), int(h["uv_mapping_version"])
    if lv != LAYOUT_VERSION or uv != UV_MAPPING_VERSION:
        raise LayoutError("skyd publishes shared-memory layout %d (uv mapping %d); this skyd "
                          "package reads layout %d (uv mapping %d): install the package that "
                          "comes with this skyd" % (lv, uv, LAYOUT_VERSION, UV_MAPPING_VERSION))
    n_slots, n_tables = int(h["n_slots"]), int(h["n_tables"])
    header_bytes, slot_bytes = int(h["header_bytes"]), int(h["slot_bytes"])
    total = int(h["total_bytes"])
    if (n_slots < MIN_SLOTS or n_slots > 1024 or n_tables > MAX_TABLES or header_bytes < HDR_BYTES
            or slot_bytes < SLOT_BYTES or total > map_bytes or slot_bytes > total
            or header_bytes + n_slots * slot_bytes > total):
        raise LayoutError("the shared memory's header describes slots outside it")
    aerial = None
    for n in range(n_tables):
        d = h["tables"][n]
        tb = {FORMAT_RGBA32F: 16, FORMAT_RGBA16F: 8}.get(int(d["format"]), 0)
        w, hh, dd = int(d["width"]), int(d["height"]), int(d["depth"])
        off, nbytes = int(d["offset"]), int(d["bytes"])
        if (not tb or int(d["texel_bytes"]) != tb or int(d["id"]) >= MAX_TABLES or not w or not hh
                or not dd or max(w, hh, dd) > 65536):
            raise LayoutError("table %d of the shared memory is malformed" % n)
        if (nbytes != w * hh * dd * tb or off < SLOT_BYTES or off > slot_bytes
                or nbytes > slot_bytes - off or off % 8):
            raise LayoutError("table %d lies outside its slot" % n)
        if int(d["id"]) == 3:
            aerial = nbytes
    max_views = int(h["max_views"])
    if max_views > MAX_VIEWS:
        raise LayoutError("%d views: at most %d" % (max_views, MAX_VIEWS))
    if max_views:
        vo, vs = int(h["view_offset"]), int(h["view_stride"])
        if (aerial is None or vs < aerial or vo % 8 or vo < SLOT_BYTES or vo > slot_bytes
                or vs * max_views > slot_bytes - vo):
            raise LayoutError("the views' volumes lie outside their slot")


def _futex_syscall():
    return {"x86_64": 202, "aarch64": 98, "riscv64": 98, "ppc64le": 221, "ppc64": 221,
            "s390x": 238, "i686": 240, "i386": 240, "armv7l": 240}.get(platform.machine())


class _Timespec(ctypes.Structure):
    _fields_ = [("tv_sec", ctypes.c_long), ("tv_nsec", ctypes.c_long)]


_SYS_FUTEX = _futex_syscall()
_LIBC = ctypes.CDLL(None, use_errno=True)
_LIBC.syscall.restype = ctypes.c_long


def _u32(buf, off):
    return struct.unpack_from("=I", buf, off)[0]


def _u64(buf, off):
    return struct.unpack_from("=Q", buf, off)[0]


def _i64(buf, off):
    return struct.unpack_from("=q", buf, off)[0]


class Region:
    """One mapping of skyd's shared memory (a memfd from ``subscribe``).

    Region(fd) takes the descriptor (closed by close()), checks its seals
    and header and maps it read-only and shared. copy_on_write=True maps it
    private and writable instead, for tests that provoke a torn read by
    writing a slot's sequence in their own copy of the pages (skyd's memory
    itself cannot be written: it is sealed).

    test_hook, when set, is called as test_hook(stage, slot_index, attempt)
    by snapshot() after it read a slot's first sequence (stage "picked")
    and after it copied the slot (stage "copied"): the place where a
    concurrent writer would tear the copy.
    """

    def __init__(self, fd, copy_on_write=False):
        self.fd = fd
        self._mm = None
        try:
            st = os.fstat(fd)
            seals = fcntl.fcntl(fd, fcntl.F_GET_SEALS)
            if not seals & fcntl.F_SEAL_SHRINK or st.st_size < HDR_BYTES:
                raise LayoutError("the shared memory is not sealed against shrinking")
            access = mmap.ACCESS_COPY if copy_on_write else mmap.ACCESS_READ
            self._mm = mmap.mmap(fd, st.st_size, access=access)
            self.identity = (st.st_dev, st.st_ino)
            self.map_bytes = st.st_size
            self.header = np.frombuffer(self._mm, HEADER_DTYPE, count=1)[0].copy()
            check_header(self.header, st.st_size)
        except BaseException:
            self.close()
            raise
        h = self.header
        self.n_slots = int(h["n_slots"])
        self.header_bytes = int(h["header_bytes"])
        self.slot_bytes = int(h["slot_bytes"])
        self.layout_version = int(h["layout_version"])
        self.uv_mapping_version = int(h["uv_mapping_version"])
        self.max_views = int(h["max_views"])
        self.view_offset = int(h["view_offset"])
        self.view_stride = int(h["view_stride"])
        infos = [TableInfo(h["tables"][n]) for n in range(int(h["n_tables"]))]
        self.tables = {t.name: t for t in infos}
        # The futex word's address, through numpy: a read-only mapping has
        # no writable buffer for ctypes.
        self._word = np.frombuffer(self._mm, np.uint32, count=1, offset=HDR_GENERATION)
        self.test_hook = None
        # A futex wait in a worker thread (the asyncio client) keeps the
        # mapping alive until it returns: close() then only marks it.
        self._lock = threading.Lock()
        self._sleepers = 0
        self._closing = False

    def close(self):
        lock = getattr(self, "_lock", None)
        if lock is not None:
            with lock:
                self._closing = True
                if self._sleepers:
                    return
        self._unmap()

    def _unmap(self):
        if self._mm is not None:
            self._word = None
            try:
                self._mm.close()
            except BufferError:
                pass            # a numpy view still holds it; freed with it
            self._mm = None
        if self.fd is not None and self.fd >= 0:
            os.close(self.fd)
        self.fd = None

    @property
    def closed(self):
        return self._mm is None or self._closing

    # The words a reader polls; plain loads (see docs/python.md on ordering).
    def generation_word(self):
        return _u32(self._mm, HDR_GENERATION)

    def current_slot(self):
        return _u32(self._mm, HDR_CURRENT_SLOT)

    def superseded(self):
        return _u32(self._mm, HDR_SUPERSEDED) != 0

    def slot_offset(self, i):
        return self.header_bytes + i * self.slot_bytes

    def _spare_ahead(self, current):
        """(seq, generation, apply_ns) of the spare slot when it is stable,
        carries an apply time and is newer than the current slot."""
        j = self.n_slots - 1
        if j == current:
            return None
        so, co = self.slot_offset(j), self.slot_offset(current)
        seq = _u32(self._mm, so + SLOT_SEQ)
        if seq & 1:
            return None
        g = _u64(self._mm, so + SLOT_GENERATION)
        at = _i64(self._mm, so + SLOT_APPLY_TIME_NS)
        cur = _u64(self._mm, co + SLOT_GENERATION)
        if _u32(self._mm, so + SLOT_SEQ) != seq or at <= 0 or g <= cur:
            return None
        return seq, g, at

    def pick(self):
        """(slot index, even sequence, generation, wake_ns) of the newest slot
        whose apply time has passed, or None while the current slot is
        being written. wake_ns is the apply time of a spare slot still
        ahead (0: none). The generation is the slot's own, the number
        ``sample`` and ``set`` speak of."""
        i = self.current_slot()
        if i >= self.n_slots:
            raise ProtocolError("current_slot %d of %d slots" % (i, self.n_slots))
        wake = 0
        ahead = self._spare_ahead(i)
        if ahead:
            seq, g, at = ahead
            if at <= time.time_ns():
                return self.n_slots - 1, seq, g, 0
            wake = at
        off = self.slot_offset(i)
        s = _u32(self._mm, off + SLOT_SEQ)
        if s & 1:
            return None
        return i, s, _u64(self._mm, off + SLOT_GENERATION), wake

    def visible_generation(self):
        """(generation a snapshot would get now, wake_ns); the slot being
        written when none is stable is reported as generation None."""
        p = self.pick()
        return (None, 0) if p is None else (p[2], p[3])

    def snapshot(self, tries=SNAPSHOT_TRIES):
        """A consistent copy of the newest slot (PROTOCOL.md's recipe: read
        the sequence, copy, read it again, retry if it moved or was odd)."""
        from ._snapshot import Snapshot
        retries = 0
        for attempt in range(tries):
            p = self.pick()
            if p is None:
                retries += 1
                os.sched_yield()
                continue
            i, s1, gen, _ = p
            off = self.slot_offset(i)
            if self.test_hook:
                self.test_hook("picked", i, attempt)
            data = self._mm[off:off + self.slot_bytes]
            if self.test_hook:
                self.test_hook("copied", i, attempt)
            if _u32(self._mm, off + SLOT_SEQ) != s1:
                retries += 1
                os.sched_yield()
                continue
            return Snapshot(self, data, i, gen, retries)
        raise TornReadError("the slot changed under each of %d copies" % tries)

    def futex_wait(self, word, timeout_s):
        """Sleeps while the generation word holds word, at most timeout_s
        (None: no bound). Returns on a wake-up, a change or the timeout."""
        with self._lock:
            if self._closing or self._mm is None:
                return
            self._sleepers += 1
        try:
            self._futex_wait(word, timeout_s)
        finally:
            with self._lock:
                self._sleepers -= 1
                last = self._closing and not self._sleepers
            if last:
                self._unmap()

    def _futex_wait(self, word, timeout_s):
        if _SYS_FUTEX is None:
            # No futex number known for this machine: look again shortly.
            time.sleep(0.01 if timeout_s is None else min(timeout_s, 0.01))
            return
        ts = None
        if timeout_s is not None:
            t = max(timeout_s, 0.0)
            ts = _Timespec(int(t), int((t - int(t)) * 1e9))
        addr = self._word.ctypes.data
        # Shared (not private) FUTEX_WAIT: the word lives in a shared mapping.
        r = _LIBC.syscall(ctypes.c_long(_SYS_FUTEX), ctypes.c_void_p(addr), ctypes.c_long(0),
                          ctypes.c_long(word), ctypes.byref(ts) if ts else None,
                          ctypes.c_void_p(0), ctypes.c_long(0))
        if r < 0:
            e = ctypes.get_errno()
            if e not in (errno.EAGAIN, errno.ETIMEDOUT, errno.EINTR):
                raise OSError(e, os.strerror(e))

    def __repr__(self):
        return "Region(layout %d, %d slots of %d bytes, %s)" % (
            self.layout_version, self.n_slots, self.slot_bytes, ", ".join(self.tables))


def checksum_words(h, data, offset, nbytes):
    """FNV-1a 64 over nbytes // 8 native-endian words of data at offset."""
    words = np.frombuffer(data, np.uint64, count=nbytes // 8, offset=offset).tolist()
    mask = (1 << 64) - 1
    for w in words:
        h = ((h ^ w) * CHECKSUM_PRIME) & mask
    return h
