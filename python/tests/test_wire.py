"""The text protocol without a daemon: request lines, values both ways, ACK
lines, events, and descriptors handed to the line they came with."""

import datetime
import os

import numpy as np
import pytest

import skyd
from skyd import _wire as w


def test_request_lines():
    assert w.format_request("set", sun_elevation_deg=12.5, ground_albedo=(0.1, 0.2, 0.3)) == \
        b"set sun_elevation_deg=12.5 ground_albedo=0.1,0.2,0.3\n"
    assert w.format_request("view", "add", name="left", yaw_deg=135) == \
        b"view add name=left yaw_deg=135\n"
    assert w.format_request("set", metar="EGLL 241250Z 9999") == b'set metar="EGLL 241250Z 9999"\n'
    assert w.format_request("subscribe", events=True) == b"subscribe events=1\n"
    assert w.format_request("set", ozone_scale_height_km=None) == \
        b"set ozone_scale_height_km=none\n"


def test_values_as_the_protocol_writes_them():
    paris = datetime.timezone(datetime.timedelta(hours=2))
    utc = datetime.datetime(2026, 6, 21, 20, 30, tzinfo=paris)
    assert w.format_value(utc) == "2026-06-21T18:30:00Z"
    assert w.format_value(datetime.date(2026, 12, 21)) == "2026-12-21"
    assert w.format_value(np.float32(0.5)) == "0.5"
    assert w.format_value(np.int64(7)) == "7"
    assert w.format_value(np.array([1.0, 2.0, 3.0])) == "1.0,2.0,3.0"
    assert w.format_value(1e-5) == "1e-05"
    assert w.format_value(float("nan")) == "nan"      # skyd refuses it with ACK [2]
    with pytest.raises(ValueError):
        w.format_value(datetime.datetime(2026, 6, 21))   # naive: which zone?
    with pytest.raises(ValueError):
        w.format_value('say "hi"')
    with pytest.raises(ValueError):
        w.format_value("two\nlines")
    with pytest.raises(ValueError):
        w.format_request("set", **{"Bad-Key": 1})
    with pytest.raises(ValueError):
        w.format_request("get", *(["x"] * 129))
    with pytest.raises(ValueError):
        w.format_request("set", metar="x" * 5000)


def test_values_from_replies():
    assert w.parse_value("12.5") == 12.5
    assert w.parse_value("192") == 192 and isinstance(w.parse_value("192"), int)
    assert isinstance(w.parse_value("192", ints=False), float)
    assert w.parse_value("0.3,0.3,0.3") == (0.3, 0.3, 0.3)
    assert w.parse_value("skyview,aerial") == ("skyview", "aerial")
    assert w.parse_value("none") is None
    assert w.parse_value("llvmpipe (LLVM 15.0.6, 256 bits)") == "llvmpipe (LLVM 15.0.6, 256 bits)"
    assert w.parse_value("BH1750_at_0x23,_MT_31") == "BH1750_at_0x23,_MT_31"
    assert w.parse_value("-1e+06") == -1e6
    assert w.typed("name=left index=0 valid=1") == {"name": "left", "index": 0, "valid": 1}


def test_ack_lines():
    e = w.parse_ack("ACK [51] {set} sun_elevation_deg: 100 is outside [-90, 90]")
    assert (e.code, e.name, e.verb, e.key, e.line) == (51, "range", "set", "sun_elevation_deg",
                                                       None)
    assert e.code == skyd.Ack.RANGE
    assert str(e) == "ACK [51] {set} sun_elevation_deg: 100 is outside [-90, 90]"
    e = w.parse_ack("ACK [51] {end} line 2: sun_elevation_deg: 300 is outside [-90, 90]; "
                    "nothing applied")
    assert (e.verb, e.line, e.key) == ("end", 2, "sun_elevation_deg")
    e = w.parse_ack("ACK [4] {set} controller role needed: uid 1000 reads only")
    assert (e.name, e.key) == ("permission", None)
    e = w.parse_ack("ACK [53] {} request line over SKY_PROTO_LINE_MAX bytes")
    assert (e.code, e.verb) == (53, "")
    assert w.parse_ack("ACK [99] {x} y").name == "unknown_code"
    with pytest.raises(skyd.ProtocolError):
        w.parse_ack("OK")


def test_greeting():
    v = w.PROTOCOL_VERSION
    assert w.parse_greeting("OK skyd %s" % v) == v
    with pytest.raises(skyd.ProtocolError):
        w.parse_greeting("OK skyd %d" % (int(v.split(".")[0]) - 1))
    with pytest.raises(skyd.ProtocolError):
        w.parse_greeting("SSH-2.0-OpenSSH")
    with pytest.raises(skyd.SkyError) as e:
        w.parse_greeting("ACK [52] {connect} too many connections (max_connections = 1024)")
    assert e.value.code == 52


def test_replies_and_events_between_them():
    r = w.ReplyReader()
    assert r.push("changed: generation=10 tables=skyview,aerial").kind == "changed"
    assert r.push("generation: 11") is None
    assert r.push("table: name=skyview format=rgba32f width=192") is None
    assert r.push("table: name=aerial format=rgba32f width=32") is None
    assert r.push("failed: generation=12 message=vkQueueSubmit:_VK_ERROR_DEVICE_LOST").kind == \
        "failed"
    reply = r.push("OK")
    assert reply["generation"] == "11"
    d = reply.to_dict()
    assert d["generation"] == 11 and [t["name"] for t in d["table"]] == ["skyview", "aerial"]
    ev = [r.events.popleft(), r.events.popleft()]
    assert (ev[0].kind, ev[0].generation, ev[0].tables) == ("changed", 10, ("skyview", "aerial"))
    assert ev[1].kind == "failed" and ev[1].fields["message"].startswith("vkQueueSubmit")
    e = r.push("ACK [50] {get} colour: unknown key")
    assert isinstance(e, skyd.SkyError) and e.key == "colour"


def test_descriptors_queue_in_the_order_they_came():
    """The kernel may hand a descriptor over with bytes before its line (a
    reply, then the layout: line that carries it): the line that needs one
    takes the oldest."""
    lines = w.LineReader()
    a, b = os.pipe()
    try:
        lines.feed(b"OK\nlayout: generation=4 bytes=100\n", [a])
        lines.feed(b"generation: 5\r\nOK\n", [b])
        assert lines.next_line() == "OK"
        assert lines.next_line() == "layout: generation=4 bytes=100"
        assert lines.take_fd() == a
        assert lines.next_line() == "generation: 5"
        assert lines.next_line() == "OK"
        assert lines.next_line() is None
        assert lines.take_fds() == [b] and lines.take_fd() is None
    finally:
        os.close(a)
        os.close(b)


def test_versions_follow_the_c_headers():
    """The package's protocol and layout versions are the C headers' own:
    a bump in proto/ that the package did not follow fails here."""
    import re
    from skyd import _shm, _wire
    proto = os.path.join(os.path.dirname(__file__), "..", "..", "proto", "skyproto.h")
    with open(proto) as f:
        text = f.read()
    assert re.search(r'#define SKY_PROTO_VERSION "([0-9.]+)"', text).group(1) == _wire.PROTOCOL_VERSION
    layout = re.search(r"#define SKY_SHM_LAYOUT_VERSION (\d+)u?", text)
    assert layout and int(layout.group(1)) == _shm.LAYOUT_VERSION
