"""Every verb of the protocol through skyd.Client against the real skyd:
typed values, batches, refusals as SkyError, subscriptions and events,
views, the weather, the sensor's report."""

import datetime
import os

import pytest

import skyd


def test_socket_found_as_skyctl_finds_it(daemon, tmp_path, monkeypatch):
    (tmp_path / "skyd").mkdir()
    os.symlink(daemon.socket, tmp_path / "skyd" / "control")
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))
    assert skyd.default_path() == str(tmp_path / "skyd" / "control")
    with skyd.Client() as c:
        assert c.protocol == skyd.PROTOCOL_VERSION
        c.ping()
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path / "nothing"))
    assert skyd.default_path() == "/run/skyd/control"
    monkeypatch.setenv("XDG_RUNTIME_DIR", "relative")
    assert skyd.default_path() == "/run/skyd/control"


def test_set_names_a_generation_and_get_is_typed(client):
    g = client.set(sun_elevation_deg=12.5, sun_azimuth_deg=100, ground_albedo=(0.1, 0.2, 0.3))
    assert isinstance(g, int) and g >= 1
    assert client.last_generation == g
    assert client.get("sun_elevation_deg") == 12.5
    assert isinstance(client.get("skyview_width"), float)
    assert client.get("ground_albedo") == (0.1, 0.2, 0.3)
    assert client.get("preset") == "earth"
    assert client.get("ozone_scale_height_km") is None
    both = client.get("sun_elevation_deg", "sun_azimuth_deg")
    assert both == {"sun_elevation_deg": 12.5, "sun_azimuth_deg": 100.0}
    every = client.get()
    assert every["sun_azimuth_deg"] == 100.0 and len(every) > 50
    # A change that changes nothing names the generation already visible.
    assert client.set(sun_elevation_deg=12.5) == client.status()["generation"]
    client.set(ground_albedo=0.3)


def test_times_and_the_clock(client):
    utc = datetime.datetime(2026, 6, 21, 18, 30, tzinfo=datetime.timezone.utc)
    if client.get("utc") is None:
        with pytest.raises(skyd.SkyError) as e:
            client.get("sun")
        assert (e.value.code, e.value.key) == (skyd.Ack.STATE, "utc")
    client.set(utc=utc, time_rate=0, lat_deg=39.742476, lon_deg=-105.1786, site_elevation_m=1830)
    assert client.get("utc") == "2026-06-21T18:30:00Z"
    assert client.get("sun_mode") == "clock"
    sun = client.get("sun")
    assert sun["utc"] == "2026-06-21T18:30:00Z"
    assert abs(sun["elevation_deg"] - 72.2987676) < 1e-5
    times = client.get("times", date="2026-06-21")
    assert times["date"] == "2026-06-21" and times["transit_utc"].startswith("2026-06-21T")
    assert 0.0 <= client.get("moon")["illuminated_fraction"] <= 1.0
    client.set(sun_elevation_deg=30, sun_azimuth_deg=180, moon_elevation_deg=-30)


def test_refusals_are_sky_errors_and_change_nothing(client):
    before = client.get("sun_elevation_deg")
    cases = [
        (lambda: client.set(sun_elevation_deg=100), skyd.Ack.RANGE, "set", "sun_elevation_deg"),
        (lambda: client.set(sun_elevation_deg=5, nosuchkey=1), skyd.Ack.NO_EXIST, "set",
         "nosuchkey"),
        (lambda: client.set(sun_elevation_deg="abc"), skyd.Ack.ARG, "set", "sun_elevation_deg"),
        (lambda: client.set(sun_elevation_deg=float("inf")), skyd.Ack.ARG, "set",
         "sun_elevation_deg"),
        (lambda: client.get("colour"), skyd.Ack.NO_EXIST, "get", "colour"),
        (lambda: client.request("frobnicate"), skyd.Ack.UNKNOWN, "frobnicate", None),
        (lambda: client.request("set novalue"), skyd.Ack.SYNTAX, "set", None),
        (lambda: client.request("end"), skyd.Ack.STATE, "end", None),
        (lambda: client.request("get " + " ".join(["x"] * 129)), skyd.Ack.LIMIT, "get", None),
        (lambda: client.subscribe("clouds"), None, None, None),
    ]
    for call, code, verb, key in cases:
        if code is None:
            with pytest.raises(ValueError):
                call()
            continue
        with pytest.raises(skyd.SkyError) as e:
            call()
        assert (e.value.code, e.value.verb, e.value.key) == (code, verb, key), e.value
    with pytest.raises(skyd.SkyError) as e:
        client._call(b"get " + b"x" * 5000 + b"\n")     # past the line limit, sent anyway
    assert e.value.code == skyd.Ack.TOO_LONG
    client.ping()                                       # the connection goes on
    assert client.get("sun_elevation_deg") == before


def test_batch_applies_as_one_change_or_not_at_all(client):
    with client.batch() as b:
        b.set(sun_elevation_deg=20)
        b.set(mie_g=0.7, sun_azimuth_deg=90)
    assert b.generation == client.last_generation
    assert client.get("sun_elevation_deg", "mie_g", "sun_azimuth_deg") == {
        "sun_elevation_deg": 20.0, "mie_g": 0.7, "sun_azimuth_deg": 90.0}
    with pytest.raises(skyd.SkyError) as e:
        with client.batch() as b:
            b.set(sun_elevation_deg=30)
            b.set(sun_elevation_deg=300)
    assert (e.value.code, e.value.verb, e.value.line, e.value.key) == (51, "end", 2,
                                                                      "sun_elevation_deg")
    with pytest.raises(RuntimeError):
        with client.batch() as b:
            b.set(sun_elevation_deg=40)
            raise RuntimeError("the block failed: nothing is sent")
    assert client.get("sun_elevation_deg") == 20.0
    client.set(mie_g=0.8, sun_elevation_deg=30, sun_azimuth_deg=180)


def test_status_commands_help(client):
    st = client.status()
    assert str(st["protocol"]) == skyd.PROTOCOL_VERSION and st["role"] == "controller"
    assert isinstance(st["generation"], int) and st["device"]
    assert st["sync"] == "off"
    verbs = {"set", "get", "batch", "subscribe", "sample", "view", "sensor"}
    assert verbs <= set(client.commands())
    h = client.help("subscribe")
    assert h["usage"].startswith("subscribe")


def test_subscribe_maps_the_memory_and_events_come(daemon, client):
    reply = client.subscribe("skyview", events=True)
    assert reply["layout_version"] == skyd.LAYOUT_VERSION and reply["events"] == 1
    assert [t["name"] for t in reply["table"]] == list(client.region.tables)
    assert client.region.tables["skyview"].shape == (16, 32, 4)
    with skyd.Client(daemon.socket) as other:
        g = other.set(sun_azimuth_deg=123)
    seen = [ev for ev in _until(client.events(timeout=60), lambda e: e.kind == "changed"
                                and e.generation >= g)]
    assert seen[-1].kind == "changed" and "skyview" in seen[-1].tables
    client.subscribe(events=False)
    client.set(sun_azimuth_deg=180)
    assert list(client.events(timeout=0.2)) == []
    client.unsubscribe()


def _until(events, stop):
    for ev in events:
        yield ev
        if stop(ev):
            return


def test_a_new_layout_comes_as_an_event_with_its_memory(client):
    client.subscribe("all", events=True)
    old = client.region
    client.set(skyview_width=48)
    ev = next(e for e in client.events(timeout=60) if e.kind == "layout")
    assert ev.generation >= 1 and client.region is not old
    assert old.closed
    assert client.tables().skyview.shape == (16, 48, 4)
    client.set(skyview_width=32)
    assert client.tables().skyview.shape == (16, 32, 4)
    client.unsubscribe()


def test_sample_verb(client):
    s = client.sample("sky", el_deg=20, az_deg=180)
    assert s.what == "sky" and len(s.rgb) == 3 and s.value > 0 and s.generation >= 1
    assert client.sample("sun").value > 0
    assert client.sample("ambient").value > 0
    with pytest.raises(skyd.SkyError) as e:
        client.sample("moon")
    assert (e.value.code, e.value.key) == (50, "moon")
    with pytest.raises(skyd.SkyError) as e:
        client.sample("sky", el_deg=95, az_deg=0)
    assert (e.value.code, e.value.key) == (51, "el_deg")


def test_views_belong_to_their_connection(daemon, client):
    g = client.view_add("left", yaw_deg=135, vfov_deg=45)
    client.view_add("wall0", form="panorama", yaw_deg=0, vfov_deg=40, aspect=1.6)
    views = {v["name"]: v for v in client.views()}
    assert views["left"]["yaw_deg"] == 135 and views["left"]["mine"] == 1
    assert views["wall0"]["form"] == "panorama"
    snap = client.tables(at_least=g)
    assert snap.views["left"].array.shape == snap.aerial.shape
    assert snap.views["left"].form == "volume"
    pano = snap.views["wall0"]
    assert pano.form == "panorama" and pano.array.shape[0] == snap.aerial.shape[0]
    with skyd.Client(daemon.socket) as other:
        with pytest.raises(skyd.SkyError) as e:
            other.view_add("left")
        assert (e.value.code, e.value.key) == (skyd.Ack.ARG, "name")
        assert "another connection" in e.value.message
    with pytest.raises(skyd.SkyError) as e:
        client.view_add("bad", form="cylinder")
    assert (e.value.code, e.value.key) == (2, "form")
    client.view_del("left")
    client.view_del("wall0")
    assert client.views() == []
    with pytest.raises(skyd.SkyError) as e:
        client.view_del("nobody")
    assert (e.value.code, e.value.key) == (50, "name")


def test_metar_and_weather(client):
    r = client.metar("EGLL 241250Z 27008KT 9999 FEW030 12/06 Q1018")
    assert r["generation"] >= 1 and r["metar_used"] == "27008KT 9999 FEW030 12/06 Q1018"
    assert r["metar_applied"]["cloud_oktas"] == 1.5
    assert client.get("cloud_oktas") == 1.5
    weather = client.get("weather")
    assert weather["cloud_oktas"] == 1.5 and "mie_g" in weather
    with pytest.raises(skyd.SkyError) as e:
        client.metar("EGLL 241250Z 27008KT 9999X FEW030")
    assert (e.value.code, e.value.key) == (2, "metar")
    client.set(visibility_km="auto", relative_humidity="auto", aerosol="auto", cloud_oktas="auto",
               pressure_mbar=1013.25, temperature_c=15)


def test_sensor_report(client):
    rep = client.sensor()
    assert rep["mode"] == "off" and "accepted" in rep
    assert client.sensor_list() == []
    client.sensor_events(True)
    client.sensor_events(False)
    with pytest.raises(skyd.SkyError) as e:
        client.set(sensor_mode="telepathy")
    assert e.value.key == "sensor_mode"


def test_close_verb(daemon):
    c = skyd.Client(daemon.socket, reconnect=False)
    c.quit()
    with pytest.raises(ConnectionError):
        c.ping()
