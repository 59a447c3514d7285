"""The shared memory as numpy arrays: shapes and dtypes, the layout against
the C compiler's, half floats scaled back, the seqlock's retry on a torn
copy (provoked in a private copy-on-write mapping of the region), the
checksum, waiting for a generation, and refusing a layout of another
version."""

import fcntl
import mmap
import os
import struct
import subprocess
import threading

import numpy as np
import pytest

import skyd
from skyd import _shm


def test_tables_as_arrays_of_the_documented_shapes(client):
    g = client.set(sun_elevation_deg=12)
    snap = client.tables()
    assert snap.generation >= g
    assert snap.valid == ("transmittance", "multiscatter", "skyview", "aerial")
    assert snap.transmittance.shape == (16, 64, 4)
    assert snap.multiscatter.shape == (8, 8, 4)
    assert snap.skyview.shape == (16, 32, 4)
    assert snap.aerial.shape == (4, 8, 8, 4)
    for name, a in snap.tables.items():
        assert a.dtype == np.float32 and not a.flags.writeable, name
        assert np.isfinite(a).all(), name
    assert abs(snap.state.sun_elevation_deg - 12.0) < 1e-9
    assert snap.state.sun_azimuth_deg == pytest.approx(180.0)
    assert snap.state.utc is None and snap.apply_time is None
    assert snap.state.bottom_radius_km == 6360.0
    assert 0.0 < snap.transmittance[..., :3].min() and snap.transmittance[..., :3].max() <= 1.0
    assert snap.verify()
    # What the table says at a texel is what the slot holds there.
    info = snap.layout["skyview"]
    raw = np.frombuffer(snap.raw, np.float32, 16 * 32 * 4, info.offset).reshape(16, 32, 4)
    assert np.array_equal(raw, snap.skyview)


def test_read_your_writes(client):
    for el in (5.0, 25.0, 45.0):
        client.set(sun_elevation_deg=el)
        assert abs(client.tables().state.sun_elevation_deg - el) < 1e-9


def test_layout_offsets_are_the_c_compilers(probe):
    out = subprocess.run([probe, "layout"], check=True, capture_output=True, text=True).stdout
    c = dict(line.rsplit(" ", 1) for line in out.splitlines())
    c = {k: int(v) for k, v in c.items()}
    assert c["sky_shm_header"] == _shm.HDR_BYTES == _shm.HEADER_DTYPE.itemsize
    assert c["sky_shm_slot"] == _shm.SLOT_BYTES
    assert c["sky_shm_state"] == _shm.STATE_DTYPE.itemsize == _shm.STATE_BYTES
    assert c["sky_shm_view"] == _shm.VIEW_DTYPE.itemsize
    assert c["sky_shm_panorama"] == _shm.PANORAMA_DTYPE.itemsize
    assert c["sky_shm_table"] == _shm.TABLE_DTYPE.itemsize
    fields = {"sky_shm_header": _shm.HEADER_DTYPE, "sky_shm_state": _shm.STATE_DTYPE,
              "sky_shm_view": _shm.VIEW_DTYPE, "sky_shm_panorama": _shm.PANORAMA_DTYPE,
              "sky_shm_table": _shm.TABLE_DTYPE}
    for key, off in c.items():
        if "." not in key:
            continue
        struct_name, field = key.split(".")
        if struct_name == "sky_shm_slot":
            assert getattr(_shm, "SLOT_" + field.upper()) == off, key
        else:
            assert fields[struct_name].fields[field][1] == off, key
    assert c["sky_shm_header.generation"] == _shm.HDR_GENERATION
    assert c["sky_shm_header.current_slot"] == _shm.HDR_CURRENT_SLOT
    assert c["sky_shm_header.superseded"] == _shm.HDR_SUPERSEDED


def test_half_floats_are_scaled_back_exactly(client):
    client.set(storage="f16")
    try:
        snap = client.tables()
        assert snap.layout["skyview"].format == "rgba16f"
        k = snap.state.rgb_scale_log2
        assert k[0] == -15                      # transmittance: largest value 1
        for name in snap.valid:
            info = snap.layout[name]
            half = np.frombuffer(snap.raw, np.float16, info.width * info.height * info.depth * 4,
                                 info.offset).reshape(info.shape).astype(np.float64)
            want = half.copy()
            want[..., :3] *= 2.0 ** k[info.id]
            assert np.array_equal(snap.table(name).astype(np.float64), want), name
            assert snap.table(name).dtype == np.float32
        assert snap.verify()
    finally:
        client.set(storage="f32")
    assert client.tables().layout["skyview"].format == "rgba32f"


def _private(client):
    """The client's region mapped again, private and writable: the pages a
    test writes are its own, the rest still skyd's."""
    return skyd.Region(os.dup(client.region.fd), copy_on_write=True)


def _seq(region, slot):
    return struct.unpack_from("=I", region._mm, region.slot_offset(slot))[0]


def _put_seq(region, slot, value):
    struct.pack_into("=I", region._mm, region.slot_offset(slot), value)


def test_a_torn_copy_is_retried(client):
    """skyd rewriting the slot while it is copied moves its sequence: the
    hook moves it, between the copy and the check, in a private mapping."""
    honest = client.tables()
    region = _private(client)
    calls = []

    def writer(stage, slot, attempt):
        calls.append((stage, attempt))
        if stage == "copied" and attempt == 0:
            _put_seq(region, slot, _seq(region, slot) + 2)

    region.test_hook = writer
    try:
        snap = region.snapshot()
    finally:
        region.close()
    assert snap.retries == 1
    assert calls == [("picked", 0), ("copied", 0), ("picked", 1), ("copied", 1)]
    assert snap.generation == honest.generation
    for name in honest.valid:
        assert np.array_equal(snap.table(name), honest.table(name))


def test_a_slot_being_written_is_not_copied(client):
    """An odd sequence at the start: the slot is half written; the reader
    looks again (here after the hook made it even, as skyd would finish)."""
    client.tables()
    region = _private(client)
    slot = region.current_slot()
    even = _seq(region, slot)
    _put_seq(region, slot, even + 1)
    tries = []

    def writer(stage, slot_index, attempt):
        tries.append((stage, attempt))

    region.test_hook = writer
    try:
        with pytest.raises(skyd.TornReadError):
            region.snapshot(tries=3)
        assert tries == []                      # never picked: nothing copied
        _put_seq(region, slot, even + 2)
        snap = region.snapshot()
    finally:
        region.close()
    assert snap.retries == 0 and tries == [("picked", 0), ("copied", 0)]


def test_a_slot_torn_every_time_gives_up(client):
    client.tables()
    region = _private(client)
    region.test_hook = lambda stage, slot, attempt: stage == "copied" and _put_seq(
        region, slot, _seq(region, slot) + 2)
    try:
        with pytest.raises(skyd.TornReadError):
            region.snapshot()
    finally:
        region.close()


def test_the_checksum_sees_what_the_sequence_cannot(client):
    """A write that left the sequence alone (which skyd never does) passes
    the seqlock; verify() catches it."""
    client.tables()
    region = _private(client)
    try:
        slot = region.current_slot()
        off = region.slot_offset(slot) + region.tables["skyview"].offset
        struct.pack_into("=f", region._mm, off, 1234.5)
        snap = region.snapshot()
    finally:
        region.close()
    assert snap.skyview[0, 0, 0] == np.float32(1234.5)
    assert not snap.verify()


def test_the_region_cannot_be_written(client):
    client.tables()
    with pytest.raises(TypeError):
        client.region._mm[0:4] = b"\0\0\0\0"
    with pytest.raises(PermissionError):
        mmap.mmap(client.region.fd, 4096, mmap.MAP_SHARED, mmap.PROT_READ | mmap.PROT_WRITE)
    seals = fcntl.fcntl(client.region.fd, fcntl.F_GET_SEALS)
    assert seals & fcntl.F_SEAL_SHRINK and seals & fcntl.F_SEAL_SEAL


def test_wait_for_a_newer_generation(daemon, client):
    g = client.tables().generation
    done = []

    def other():
        with skyd.Client(daemon.socket) as o:
            done.append(o.set(sun_azimuth_deg=170 + len(done)))

    t = threading.Thread(target=other)
    t.start()
    try:
        got = client.wait(g, timeout=60)
    finally:
        t.join()
    assert got > g
    now = client.region.visible_generation()[0]
    with pytest.raises(TimeoutError):
        client.wait(now, timeout=0.2)
    client.set(sun_azimuth_deg=180)


def _fake_region(magic=_shm.MAGIC, layout=_shm.LAYOUT_VERSION, uv=_shm.UV_MAPPING_VERSION,
                 seal=True):
    fd = os.memfd_create("skyd-test", os.MFD_CLOEXEC | os.MFD_ALLOW_SEALING)
    header = np.zeros(1, _shm.HEADER_DTYPE)
    header["magic"], header["layout_version"], header["uv_mapping_version"] = magic, layout, uv
    header["header_bytes"], header["n_slots"], header["slot_bytes"] = 4096, 3, 4096
    header["total_bytes"] = 4096 * 4
    os.ftruncate(fd, 4096 * 4)
    os.pwrite(fd, header.tobytes(), 0)
    if seal:
        fcntl.fcntl(fd, fcntl.F_ADD_SEALS, fcntl.F_SEAL_SHRINK | fcntl.F_SEAL_GROW)
    return fd


def test_another_layout_is_refused_clearly():
    region = skyd.Region(_fake_region())        # a well-formed empty region reads
    assert region.tables == {} and region.n_slots == 3
    region.close()
    with pytest.raises(skyd.LayoutError) as e:
        skyd.Region(_fake_region(layout=9))
    assert "layout 9" in str(e.value) and "reads layout 8" in str(e.value)
    with pytest.raises(skyd.LayoutError) as e:
        skyd.Region(_fake_region(uv=5))
    assert "uv mapping 5" in str(e.value)
    with pytest.raises(skyd.LayoutError):
        skyd.Region(_fake_region(magic=0x12345678))
    with pytest.raises(skyd.LayoutError) as e:
        skyd.Region(_fake_region(seal=False))
    assert "sealed" in str(e.value)
    assert issubclass(skyd.LayoutError, skyd.ProtocolError)
