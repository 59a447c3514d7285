"""skyd for Python: drive the sky daemon and read its tables as numpy arrays.

skyd computes the lookup tables of a physically based sky (transmittance,
multi-scattering, sky-view, aerial perspective) and publishes them in
shared memory; a text protocol on a Unix socket steers it. This package
speaks that protocol (proto/PROTOCOL.md, protocol 7.1) and maps the shared
memory read-only (layout 8), with nothing beyond the standard library and
numpy.

CONNECTING

    import skyd
    c = skyd.Client()                  # the socket skyctl finds
    c = skyd.Client("/run/user/1000/skyd/control", timeout=10)

    Without a path: $XDG_RUNTIME_DIR/skyd/control when that socket exists,
    else /run/skyd/control. With reconnect=True (the default) a call that
    finds skyd gone (restarted) connects again and renews the subscription.

CHANGING THE SKY

    g = c.set(sun_elevation_deg=10, sun_azimuth_deg=120)   # -> generation
    c.set(ground_albedo=(0.1, 0.2, 0.3), utc=datetime.now(timezone.utc))
    with c.batch() as b:               # one change, one computation
        b.set(preset="earth")
        b.set(sun_elevation_deg=20, mie_g=0.7)
    b.generation
    c.metar("EGLL 241250Z 27008KT 9999 FEW030 12/06 Q1018")

    Values: numbers, r,g,b sequences, strings (quoted when they hold
    spaces), None for "none", aware datetimes for utc. A request applies
    whole or not at all.

READING THE STATE

    c.get("sun_elevation_deg")  -> 10.0          (float, tuple, str or None)
    c.get("ground_albedo")      -> (0.1, 0.2, 0.3)
    c.get()                     -> {key: value} of every key
    c.get("sun"), c.get("moon"), c.get("times", date="2026-06-21"),
    c.get("weather"), c.get("sensor")           -> reports as dicts
    c.status()                  -> dict; c.commands(); c.help("set"); c.ping()
    c.sample("sky", el_deg=20, az_deg=180)      -> Sample (skyd samples)
    c.sample("sun"); c.sample("ambient")
    c.view_add("left", yaw_deg=135, form="panorama"); c.views(); c.view_del("left")
    c.sensor(); c.sensor_list(); c.sensor_events(True)
    c.request("any verb key=value")             -> Reply

ERRORS

    skyd.SkyError: skyd refused (an ACK line). e.code (skyd.Ack.RANGE ...),
    e.name ("range"), e.verb, e.key (the key named, or None), e.message,
    e.line (the batch line at fault). Nothing changed.
    skyd.ProtocolError: skyd said something unreadable; skyd.LayoutError:
    shared memory of another layout version (install the matching package).
    TimeoutError and ConnectionError as the standard library's.

THE TABLES AS ARRAYS

    snap = c.tables()            # subscribes to all tables on first use
    snap.generation, snap.state, snap.apply_time
    snap.transmittance           # float32 (height, width, 4)
    snap.multiscatter            # float32 (height, width, 4)
    snap.skyview                 # float32 (height, width, 4)
    snap.aerial                  # float32 (depth, height, width, 4)
    snap.views["left"].array     # a view's volume or panorama

    tables() copies the newest slot under its seqlock (retrying a torn
    copy) and waits until the tables are valid and the generation is at
    least that of this client's last change. Rows run bottom-up in v
    (proto/skymap.h); RGB of half-float tables is scaled back (exact).
    c.wait(g) blocks until a generation after g is published (a futex
    on the shared memory); for ev in c.events(): changed:, layout:, failed:
    and sensor: lines (subscribe(events=True) or sensor_events()).

SAMPLING, ON A SNAPSHOT (numpy, vectorised, float64)

    snap.sky_radiance(el_deg, az_deg)            -> (..., 3) cd/m2
    snap.sky_transmittance(el_deg)               -> (..., 3), 0 into the ground
    snap.transmittance_mu(mu, altitude_km=None)  -> (..., 3)
    snap.aerial_screen(u, v, distance_km, view=None) -> (rgb, T)
    snap.aerial_dir(directions, distance_km, view=None) -> (rgb, T)
    snap.sun_illuminance(), snap.ambient_illuminance() -> (3,) lx
    snap.fisheye(512), snap.equirect(1024), snap.perspective(640, 360)
                                                 -> float32 (h, w, 3)
    skyd.direction(el_deg, az_deg), skyd.image.luminance(rgb)
    skyd.image.to_srgb8(rgb), skyd.image.write_png(path, pixels)

    These follow proto/skymap.h and proto/skysample.h operation for
    operation: they agree with libsky's CPU sampling and with skyd's sample
    verb for the same generation within one float32 rounding (relative
    2**-23 = 1.2e-7 per channel); docs/python.md has what was measured.

ASYNCIO

    async with skyd.AsyncClient(path) as c:
        g = await c.set(sun_elevation_deg=5)
        snap = await c.tables()
        async for ev in c.events(): ...

    Every method of Client, as a coroutine; requests from several tasks
    may overlap.
"""

from ._shm import LAYOUT_VERSION, UV_MAPPING_VERSION, LayoutError, Region, TableInfo, TornReadError
from ._snapshot import Snapshot, State, TableMissing, View, direction
from ._wire import PROTOCOL_VERSION, Ack, Event, ProtocolError, Reply, SkyError
from .aio import AsyncClient
from .client import Batch, Client, Sample, default_path
from . import image

__version__ = "0.3.0"

__all__ = [
    "Ack", "AsyncClient", "Batch", "Client", "Event", "LAYOUT_VERSION", "LayoutError",
    "PROTOCOL_VERSION", "ProtocolError", "Region", "Reply", "Sample", "SkyError", "Snapshot",
    "State", "TableInfo", "TableMissing", "TornReadError", "UV_MAPPING_VERSION", "View",
    "default_path", "direction", "image",
]
