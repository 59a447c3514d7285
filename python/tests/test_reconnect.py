"""A skyd restart under a connected client: the next call connects again,
renews the subscription and maps the new memory; wait() and events() come
back too; without reconnect the client says the connection is gone."""

import asyncio
import threading

import pytest

import skyd


def restart(daemon):
    daemon.stop()
    daemon.start()


def test_a_call_after_a_restart_connects_again(daemon):
    c = skyd.Client(daemon.socket, timeout=60)
    try:
        c.set(sun_elevation_deg=11)
        before = c.tables()
        old_region = c.region.identity
        assert abs(before.state.sun_elevation_deg - 11) < 1e-9
        restart(daemon)
        assert c.get("sun_elevation_deg") == 30.0          # a fresh skyd's default
        assert c.region.identity != old_region            # subscribed again, new memory
        assert c.last_generation == 0                     # its generations start afresh
        snap = c.tables()
        assert snap.skyview.shape == (16, 32, 4)
        assert abs(snap.state.sun_elevation_deg - 30) < 1e-9
        c.set(sun_elevation_deg=12)
        assert abs(c.tables().state.sun_elevation_deg - 12) < 1e-9
    finally:
        c.close()


def test_events_and_wait_come_back(daemon):
    c = skyd.Client(daemon.socket, timeout=60)
    try:
        c.subscribe("all", events=True)
        restart(daemon)
        ev = next(c.events(timeout=60))
        assert ev.kind == "reconnected"
        g = c.set(sun_elevation_deg=13)
        assert any(e.kind == "changed" and e.generation >= g
                   for e in _first(c.events(timeout=60), lambda e: e.generation >= g))
        seen = c.tables().generation
        t = threading.Thread(target=restart, args=(daemon,))
        t.start()
        try:
            got = c.wait(seen, timeout=60)               # ends on the new skyd's memory
        finally:
            t.join()
        assert isinstance(got, int)
        assert c.tables().skyview.shape == (16, 32, 4)
    finally:
        c.close()


def _first(events, stop):
    for ev in events:
        yield ev
        if ev.generation is not None and stop(ev):
            return


def test_without_reconnect_the_loss_is_an_error(daemon):
    c = skyd.Client(daemon.socket, reconnect=False)
    try:
        c.ping()
        restart(daemon)
        with pytest.raises(ConnectionError):
            c.ping()
    finally:
        c.close()


def test_async_client_connects_again(daemon):
    async def main():
        async with skyd.AsyncClient(daemon.socket, timeout=60) as c:
            await c.set(sun_elevation_deg=14)
            old = (await c.tables()).generation
            assert old >= 1
            restart(daemon)
            assert await c.get("sun_elevation_deg") == 30.0
            snap = await c.tables()
            assert abs(snap.state.sun_elevation_deg - 30) < 1e-9
    asyncio.run(asyncio.wait_for(main(), 120))
