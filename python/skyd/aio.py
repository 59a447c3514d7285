"""The asyncio client: the verbs of skyd.Client as coroutines over one
connection, which a reader task serves: replies in request order to their
callers, event lines to events(), new shared memory mapped as it comes."""

import asyncio
import collections
import os
import socket
import time

from . import _wire as w
from .client import RECONNECT_INTERVAL_S, SKY_TABLE_NAMES, TABLE_NAMES, Batch, Client, Sample, _Core, \
    table_names


class _Pending:
    """A caller waiting for its reply; a batch's also takes the replies of
    its lines when skyd refused the batch itself (then it opened none)."""

    def __init__(self, fut, lines_if_refused=0, maps=False):
        self.fut = fut
        self.maps = maps
        self.first = None
        self.left = None
        self.lines = lines_if_refused

    def take(self, out):
        """Takes one reply; True when this caller has all of its replies."""
        if self.first is None:
            self.first = out
            if isinstance(out, w.SkyError) and out.verb == "batch" and self.lines:
                self.left = self.lines + 1
                return False
            return True
        self.left -= 1
        return self.left == 0


class AsyncClient(_Core):
    """A connection to skyd for asyncio.

    ``c = await skyd.AsyncClient.connect(path)`` or ``async with
    skyd.AsyncClient(path) as c``; then ``await c.set(...)``,
    ``await c.get(...)``, ``async with c.batch() as b``, ``await
    c.tables()``, ``await c.wait(g)``, ``async for ev in c.events()`` and
    every other method of skyd.Client as a coroutine. Requests from several
    tasks may overlap: each gets its own reply. Arguments, return values and
    reconnection are skyd.Client's.
    """

    def __init__(self, path=None, timeout=30.0, reconnect=True):
        self._core_init(path, timeout, reconnect)
        self._pending = collections.deque()
        self._reader = None
        self._send_lock = None
        self._news = None
        self._closed = False

    @classmethod
    async def connect(cls, path=None, timeout=30.0, reconnect=True):
        c = cls(path, timeout, reconnect)
        await c._open()
        return c

    async def __aenter__(self):
        if self._sock is None:
            await self._open()
        return self

    async def __aexit__(self, *exc):
        await self.close()

    async def _open(self):
        loop = asyncio.get_running_loop()
        if self._send_lock is None:
            self._send_lock = asyncio.Lock()
            self._news = asyncio.Condition()
        s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM | socket.SOCK_CLOEXEC)
        s.setblocking(False)
        try:
            await asyncio.wait_for(loop.sock_connect(s, self.path), self.timeout)
        except BaseException:
            s.close()
            raise
        self._sock = s
        self._lines = w.LineReader()
        self._pending = collections.deque()     # this connection's callers
        try:
            text = await asyncio.wait_for(self._greeting(), self.timeout)
            self.protocol = w.parse_greeting(text)
        except BaseException:
            self._drop_connection()
            raise
        self._reader = asyncio.ensure_future(self._read_loop(s, self._pending))

    async def _readable(self, sock):
        loop = asyncio.get_running_loop()
        fut = loop.create_future()
        fd = sock.fileno()
        loop.add_reader(fd, lambda: fut.done() or fut.set_result(None))
        try:
            await fut
        finally:
            loop.remove_reader(fd)

    async def _recv_once(self, sock):
        while True:
            try:
                data, fds, _, _ = socket.recv_fds(sock, 65536, 16, socket.MSG_CMSG_CLOEXEC)
            except BlockingIOError:
                await self._readable(sock)
                continue
            if not data:
                for fd in fds:
                    os.close(fd)
                raise ConnectionResetError("skyd closed the connection")
            self._lines.feed(data, fds)
            return

    async def _greeting(self):
        while True:
            text = self._lines.next_line()
            if text is not None:
                return text
            await self._recv_once(self._sock)

    async def _read_loop(self, sock, pending):
        """Serves one connection until it ends: replies to its waiting
        callers (pending) in order, events to the queue."""
        error = None
        try:
            while True:
                await self._recv_once(sock)
                while True:
                    got = self._lines.next_line()
                    if got is None:
                        break
                    if not pending:
                        if self._line_in(got) is not None:
                            raise w.ProtocolError("a reply without a request: %r" % (got,))
                        continue
                    p = pending[0]
                    # The descriptor is taken in stream order, before any
                    # later layout: line could take it.
                    out = self._line_in(got, p.maps and p.first is None)
                    if out is None:
                        continue
                    if p.take(out):
                        pending.popleft()
                        if not p.fut.done():
                            p.fut.set_result(p.first)
                async with self._news:
                    self._news.notify_all()
        except (ConnectionResetError, OSError, w.ProtocolError) as e:
            error = e
        finally:
            if self._sock is sock:
                self._drop_connection()
            while pending:
                p = pending.popleft()
                if not p.fut.done():
                    p.fut.set_exception(ConnectionResetError(
                        "skyd went away before it answered (the request may or may not have "
                        "applied): %s" % (error or "connection closed")))
            async with self._news:
                self._news.notify_all()

    async def close(self):
        """Closes the connection and unmaps the shared memory."""
        self._closed = True
        reader, self._reader = self._reader, None
        self._drop_connection()
        if reader is not None:
            reader.cancel()
            try:
                await reader
            except (asyncio.CancelledError, Exception):
                pass
        if self.region is not None:
            self.region.close()
            self.region = None

    async def reconnect_now(self, timeout=None):
        """Connects again (retrying while skyd is not there, up to timeout
        seconds) and renews the subscription."""
        if self._reader is not None:
            self._reader.cancel()
            self._reader = None
        self._drop_connection()
        timeout = self.timeout if timeout is None else timeout
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            try:
                await self._open()
                break
            except (FileNotFoundError, ConnectionRefusedError):
                if deadline is not None and time.monotonic() + RECONNECT_INTERVAL_S > deadline:
                    raise
                await asyncio.sleep(RECONNECT_INTERVAL_S)
        before = None if self.region is None else self.region.identity
        if self._sub_tables or self._sub_events:
            await self._subscribe(self._sub_tables, self._sub_events)
        self._renumbered(before)

    async def _exchange(self, data, lines_if_refused=0, maps=False):
        if self._sock is None or self._reader is None or self._reader.done():
            if not self.reconnect or self._closed:
                raise ConnectionResetError("not connected to skyd")
            await self.reconnect_now()
        loop = asyncio.get_running_loop()
        p = _Pending(loop.create_future(), lines_if_refused, maps)
        for attempt in (0, 1):
            async with self._send_lock:
                self._pending.append(p)
                try:
                    await loop.sock_sendall(self._sock, data)
                    break
                except (BrokenPipeError, ConnectionResetError):
                    # skyd went away before any of it: send it again there.
                    self._pending.remove(p)
                    if attempt or not self.reconnect:
                        raise
            await self.reconnect_now()
        try:
            return await asyncio.wait_for(asyncio.shield(p.fut), self.timeout)
        except asyncio.TimeoutError:
            # Its reply could arrive as the next request's: start afresh.
            self._drop_connection()
            raise TimeoutError("no reply from skyd within %s s" % self.timeout) from None

    async def _call(self, data, maps=False):
        reply = await self._exchange(data, maps=maps)
        if isinstance(reply, w.SkyError):
            raise reply
        self._note_generation(data, reply)
        return reply

    async def request(self, verb, *words, **keys):
        """skyd.Client.request as a coroutine."""
        if (" " in verb or "\t" in verb) and not words and not keys:
            if "\n" in verb or "\r" in verb:
                raise ValueError("a request is one line")
            return await self._call((verb + "\n").encode("ascii"))
        return await self._call(w.format_request(verb, *words, **keys))

    async def set(self, **keys):
        if not keys:
            raise ValueError("set needs at least one key")
        return int((await self.request("set", **keys))["generation"])

    async def get(self, *keys, **args):
        return self._typed_get(keys, args, await self.request("get", *keys, **args))

    def batch(self):
        """``async with c.batch() as b: b.set(...)``: one change when the block ends."""
        return _AsyncBatch(self)

    async def _batch(self, lines):
        data = b"batch\n" + b"".join(lines) + b"end\n"
        first = await self._exchange(data, lines_if_refused=len(lines))
        if isinstance(first, w.SkyError):
            raise first
        self._note_generation(data, first)
        return first

    async def status(self):
        return (await self.request("status")).to_dict(ints=True, lists=("view",))

    async def subscribe(self, *tables, events=None):
        names = table_names(tables) if tables else ()
        return await self._subscribe(names, events)

    async def _subscribe(self, names, events):
        reply = await self._call(w.format_request("subscribe",
                                                  **self._subscribe_args(names, events)),
                                 maps=bool(names))
        if reply.map_error is not None:
            raise reply.map_error
        if names:
            self._sub_tables = names
        if events is not None:
            self._sub_events = bool(events)
        return reply.to_dict(ints=True, lists=("table",))

    async def unsubscribe(self):
        await self.request("unsubscribe")
        self._sub_tables, self._sub_events = (), False

    async def sample(self, what, **args):
        return Sample(what, await self.request("sample", what, **args))

    async def view_add(self, name, **keys):
        return int((await self.request("view", "add", name=name, **keys))["generation"])

    async def view_del(self, name):
        return int((await self.request("view", "del", name=name))["generation"])

    async def views(self):
        r = await self.request("view", "list")
        return r.to_dict(ints=True, lists=("view",)).get("view", [])

    async def metar(self, report):
        return (await self.request("set", metar=report)).to_dict(ints=True)

    async def sensor(self):
        return await self.get("sensor")

    async def sensor_list(self):
        r = await self.request("sensor", "list")
        return r.to_dict(ints=True, lists=("device",)).get("device", [])

    async def sensor_events(self, on=True):
        await self.request("sensor", events=1 if on else 0)

    async def commands(self):
        return (await self.request("commands")).getall("command")

    async def help(self, verb=None):
        r = await (self.request("help", verb) if verb else self.request("help"))
        return r.to_dict(ints=False)

    async def ping(self):
        await self.request("ping")

    async def events(self, timeout=None):
        """Yields Event objects as they come; ends when none came for timeout
        seconds (None: never). After a reconnection: an Event "reconnected"."""
        while True:
            while self._replies.events:
                yield self._replies.events.popleft()
            if self._sock is None or self._reader is None or self._reader.done():
                if not self.reconnect or self._closed:
                    raise ConnectionResetError("not connected to skyd")
                await self.reconnect_now()
                yield w.Event("reconnected", {"generation": self.last_generation}, "reconnected")
                continue
            try:
                async with self._news:
                    await asyncio.wait_for(self._news.wait_for(
                        lambda: self._replies.events or self._reader is None
                        or self._reader.done()), timeout)
            except asyncio.TimeoutError:
                return

    async def _need_region(self, names):
        names = table_names(names) if names else SKY_TABLE_NAMES
        if self.region is None or not set(names) <= set(self._sub_tables):
            await self.subscribe(*sorted(set(names) | set(self._sub_tables),
                                         key=TABLE_NAMES.index))
        return names

    async def _follow_layout(self, deadline):
        while self.region.superseded():
            old = self.region
            async with self._news:
                await asyncio.wait_for(self._news.wait_for(lambda: self.region is not old),
                                       self._left(deadline))

    @staticmethod
    def _left(deadline):
        return None if deadline is None else max(deadline - time.monotonic(), 0.0)

    async def tables(self, *names, at_least=None, timeout=None):
        """skyd.Client.tables as a coroutine."""
        names = await self._need_region(names)
        floor = self.last_generation if at_least is None else at_least
        timeout = self.timeout if timeout is None else timeout
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            await self._follow_layout(deadline)
            snap = self.region.snapshot()
            if snap.generation >= floor and set(names) <= set(snap.valid):
                return snap
            await self.wait(snap.generation, timeout=self._left(deadline))

    async def wait(self, generation=None, timeout=None):
        """skyd.Client.wait as a coroutine: the futex sleeps in a worker
        thread, a quarter of a second at a time, so that cancelling it is
        prompt."""
        await self._need_region(self._sub_tables)
        timeout = self.timeout if timeout is None else timeout
        deadline = None if timeout is None else time.monotonic() + timeout
        if generation is None:
            generation = self.region.visible_generation()[0] or 0
        while True:
            await self._follow_layout(deadline)
            region = self.region
            word = region.generation_word()
            vis, wake_ns = region.visible_generation()
            if vis is not None and vis > generation and not region.superseded():
                return vis
            left = self._left(deadline)
            if left == 0.0:
                raise TimeoutError("no generation after %d within %s s" % (generation, timeout))
            if self._reader is None or self._reader.done():
                if not self.reconnect:
                    raise ConnectionResetError("not connected to skyd")
                await self.reconnect_now(timeout=left)
                if self.region is not region:
                    return self.region.visible_generation()[0] or 0
                continue
            step = 0.25 if left is None else min(left, 0.25)
            if wake_ns:
                step = min(step, max((wake_ns - time.time_ns()) / 1e9, 0.0))
            await asyncio.to_thread(region.futex_wait, word, step)


class _AsyncBatch(Batch):
    def __init__(self, client):
        super().__init__(client._batch)

    async def __aenter__(self):
        return self

    async def __aexit__(self, exc_type, exc, tb):
        if exc_type is None:
            self._done(await self._send(self.lines))
        return False


def _borrow_docs():
    """The coroutines say what the blocking methods say, where they do not
    say it themselves."""
    for name, fn in vars(AsyncClient).items():
        if callable(fn) and not fn.__doc__ and not name.startswith("_"):
            blocking = getattr(Client, name, None)
            if blocking is not None and blocking.__doc__:
                fn.__doc__ = "As Client.%s (a coroutine): " % name + blocking.__doc__


_borrow_docs()
