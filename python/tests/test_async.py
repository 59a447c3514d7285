"""skyd.AsyncClient against the real skyd: the verbs as coroutines,
overlapping requests, a batch, refusals, events, snapshots and waiting."""

import asyncio

import numpy as np
import pytest

import skyd


def run(coro):
    return asyncio.run(asyncio.wait_for(coro, 120))


def test_verbs_as_coroutines(daemon):
    async def main():
        async with skyd.AsyncClient(daemon.socket) as c:
            assert c.protocol == skyd.PROTOCOL_VERSION
            g = await c.set(sun_elevation_deg=15, ground_albedo=(0.2, 0.2, 0.2))
            assert isinstance(g, int) and c.last_generation == g
            assert await c.get("sun_elevation_deg") == 15.0
            assert await c.get("ground_albedo") == (0.2, 0.2, 0.2)
            assert (await c.status())["role"] == "controller"
            assert "subscribe" in await c.commands()
            assert (await c.help("set"))["usage"].startswith("set")
            await c.ping()
            s = await c.sample("sky", el_deg=20, az_deg=180)
            assert s.generation >= 1 and s.value > 0
            with pytest.raises(skyd.SkyError) as e:
                await c.set(sun_elevation_deg=100)
            assert (e.value.code, e.value.key) == (skyd.Ack.RANGE, "sun_elevation_deg")
            await c.ping()
            assert (await c.metar("EGLL 241250Z 27008KT 9999 FEW030 12/06 Q1018"))["generation"]
            await c.set(visibility_km="auto", relative_humidity="auto", aerosol="auto",
                        cloud_oktas="auto")
            assert (await c.sensor())["mode"] == "off"
            assert await c.sensor_list() == []
            await c.view_add("v", yaw_deg=90)
            assert [v["name"] for v in await c.views()] == ["v"]
            await c.view_del("v")
            await c.set(ground_albedo=0.3, sun_elevation_deg=30)
    run(main())


def test_overlapping_requests_get_their_own_replies(daemon):
    async def main():
        c = await skyd.AsyncClient.connect(daemon.socket)
        try:
            keys = ["sun_elevation_deg", "sun_azimuth_deg", "preset", "skyview_width",
                    "ground_albedo", "mie_g"] * 5
            got = await asyncio.gather(*(c.get(k) for k in keys))
            want = await c.get(*keys[:6])
            assert got == [want[k] for k in keys]
            results = await asyncio.gather(c.set(sun_elevation_deg=200), c.get("mie_g"),
                                           return_exceptions=True)
            assert isinstance(results[0], skyd.SkyError) and results[1] == want["mie_g"]
        finally:
            await c.close()
    run(main())


def test_batch(daemon):
    async def main():
        async with skyd.AsyncClient(daemon.socket) as c:
            async with c.batch() as b:
                b.set(sun_elevation_deg=21)
                b.set(sun_azimuth_deg=95)
            assert b.generation == c.last_generation
            assert await c.get("sun_elevation_deg", "sun_azimuth_deg") == {
                "sun_elevation_deg": 21.0, "sun_azimuth_deg": 95.0}
            with pytest.raises(skyd.SkyError) as e:
                async with c.batch() as b:
                    b.set(sun_elevation_deg=22)
                    b.set(mie_g=5)
            assert (e.value.verb, e.value.line, e.value.key) == ("end", 2, "mie_g")
            assert await c.get("sun_elevation_deg") == 21.0
            await c.set(sun_elevation_deg=30, sun_azimuth_deg=180)
    run(main())


def test_tables_wait_and_events(daemon):
    async def main():
        async with skyd.AsyncClient(daemon.socket) as c, \
                skyd.AsyncClient(daemon.socket) as other:
            await c.set(sun_elevation_deg=33)
            snap = await c.tables()
            assert snap.skyview.shape == (16, 32, 4)
            assert abs(snap.state.sun_elevation_deg - 33) < 1e-9
            waiter = asyncio.ensure_future(c.wait(snap.generation))
            await asyncio.sleep(0)
            g = await other.set(sun_elevation_deg=34)
            assert await waiter >= g > snap.generation
            with pytest.raises(TimeoutError):
                await c.wait(c.region.visible_generation()[0], timeout=0.2)
            await c.subscribe(events=True)
            g = await other.set(sun_elevation_deg=35)
            async for ev in c.events(timeout=60):
                if ev.kind == "changed" and ev.generation >= g:
                    break
            else:
                pytest.fail("no changed: event")
            later = await c.tables(at_least=g)
            s = await c.sample("sky", el_deg=20, az_deg=180)
            if s.generation == later.generation:
                assert np.allclose(later.sky_radiance(20, 180), s.rgb, rtol=2.0 ** -23, atol=0)
            old = c.region
            await other.set(skyview_width=40)
            async for ev in c.events(timeout=60):
                if ev.kind == "layout":
                    break
            assert c.region is not old and (await c.tables()).skyview.shape == (16, 40, 4)
            await other.set(skyview_width=32, sun_elevation_deg=30)
    run(main())
