"""The blocking client: one connection to skyd's control socket, its verbs as
methods, its events as an iterator, and its shared memory as snapshots."""

import os
import select
import socket
import time

from . import _wire as w
from ._shm import SKY_TABLE_NAMES, TABLE_NAMES, Region

TOPICS = ("sun", "moon", "times", "weather", "sensor")
CHANGES = (b"set", b"batch", b"end", b"view", b"sensor")
RECONNECT_INTERVAL_S = 0.1
EVENTS_MAX = 100000


def default_path():
    """The socket skyctl and libsky find without --socket: the one under
    $XDG_RUNTIME_DIR/skyd/control when XDG_RUNTIME_DIR is an absolute path
    and that socket exists, else /run/skyd/control (libsky's sky_default_path)."""
    xdg = os.environ.get("XDG_RUNTIME_DIR")
    if xdg and xdg.startswith("/"):
        p = os.path.join(xdg, "skyd", "control")
        if os.path.exists(p):
            return p
    return "/run/skyd/control"


def table_names(names):
    """Table names (or "all") as a tuple in id order; ValueError for others."""
    out = set()
    for n in names:
        for part in str(n).split(","):
            if part == "all":
                out.update(SKY_TABLE_NAMES)
            elif part in TABLE_NAMES:
                out.add(part)
            else:
                raise ValueError("%r: not a table (%s or all)" % (part, ", ".join(TABLE_NAMES)))
    return tuple(n for n in TABLE_NAMES if n in out)


class Sample:
    """A ``sample`` reply: what, generation, rgb (a tuple of 3 floats:
    radiance_rgb_cd_m2 for sky, illuminance_rgb_lx for sun and ambient),
    value (luminance_cd_m2 or illuminance_lx) and fields (the whole reply)."""

    def __init__(self, what, reply):
        self.what = what
        self.fields = reply.to_dict(ints=True)
        self.generation = int(self.fields["generation"])
        rgb_key = "radiance_rgb_cd_m2" if what == "sky" else "illuminance_rgb_lx"
        y_key = "luminance_cd_m2" if what == "sky" else "illuminance_lx"
        self.rgb = tuple(float(x) for x in reply[rgb_key].split(","))
        self.value = float(reply[y_key])

    def __repr__(self):
        return "Sample(%r, generation=%d, rgb=%r, value=%r)" % (
            self.what, self.generation, self.rgb, self.value)


class Batch:
    """Lines of one ``batch`` ... ``end``, sent when the with-block ends
    without an exception (nothing is sent otherwise); then generation and
    reply hold the outcome, and a refusal raises SkyError naming the line."""

    def __init__(self, send):
        self._send = send
        self.lines = []
        self.generation = None
        self.reply = None

    def set(self, **keys):
        """Adds a set line (key=value arguments as Client.set takes them)."""
        if not keys:
            raise ValueError("set needs at least one key")
        self.lines.append(w.format_request("set", **keys))
        return self

    def metar(self, report):
        """Adds a set metar="..." line."""
        return self.set(metar=report)

    def _done(self, reply):
        self.reply = reply
        self.generation = int(reply["generation"])
        return self.generation


class _Core:
    """What the blocking and the asyncio clients share: the parsers, the
    subscription they renew after a reconnection, the region."""

    def _core_init(self, path, timeout, reconnect):
        self.path = default_path() if path is None else os.fspath(path)
        self.timeout = timeout
        self.reconnect = reconnect
        self.protocol = None
        self.region = None
        self.last_generation = 0
        self._sub_tables = ()
        self._sub_events = False
        self._lines = w.LineReader()
        self._replies = w.ReplyReader(EVENTS_MAX)
        self._sock = None

    def _renumbered(self, identity_before):
        """After a reconnection: a skyd that did not hand back the same memory
        numbers its generations afresh, so the last change's number means
        nothing there."""
        if self.region is None or self.region.identity != identity_before:
            self.last_generation = 0

    def _note_generation(self, line, reply):
        """A change (set, end, view add/del, sensor) names the generation
        that will show it: tables() waits for it by default."""
        verb = line.split(None, 1)[0]
        g = reply.get("generation")
        if verb in CHANGES and g is not None:
            self.last_generation = max(self.last_generation, int(g))

    def _adopt_region(self, fd):
        """Maps fd (from a subscribe or a layout: line); the memory already
        mapped (same inode and size) keeps its mapping."""
        if fd is None:
            raise w.ProtocolError("skyd sent no shared memory with its line")
        st = os.fstat(fd)
        if (self.region is not None and not self.region.closed
                and self.region.identity == (st.st_dev, st.st_ino)
                and self.region.map_bytes == st.st_size):
            os.close(fd)
            return
        new = Region(fd)
        old, self.region = self.region, new
        if old is not None:
            old.close()

    def _line_in(self, text, maps=False):
        """One received line: an event (a layout: line maps the memory that
        came with it) or part of a reply; returns a completed Reply or
        SkyError, else None. maps: an OK reply brings the shared memory
        (subscribe tables=), mapped here, in stream order, so that no later
        layout: line is taken for it; reply.map_error says why it failed."""
        out = self._replies.push(text)
        if isinstance(out, w.Event):
            if out.kind == "layout":
                self._adopt_region(self._lines.take_fd())
            return None
        if isinstance(out, w.Reply):
            out.map_error = None
            if maps:
                try:
                    self._adopt_region(self._lines.take_fd())
                except (w.ProtocolError, OSError) as e:
                    out.map_error = e
        return out

    def _drop_connection(self):
        if self._sock is not None:
            self._sock.close()
        self._sock = None
        for fd in self._lines.take_fds():
            os.close(fd)
        self._lines = w.LineReader()
        pending = self._replies.events
        self._replies = w.ReplyReader(EVENTS_MAX)
        self._replies.events = pending

    @staticmethod
    def _subscribe_args(tables, events):
        keys = {}
        if tables:
            keys["tables"] = ",".join(tables)
        if events is not None:
            keys["events"] = 1 if events else 0
        return keys

    def _typed_get(self, keys, args, reply):
        topic = len(keys) == 1 and keys[0] in TOPICS
        if len(keys) == 1 and not topic and not args and len(reply.pairs) == 1 \
                and reply.pairs[0][0] == keys[0]:
            return w.typed(reply.pairs[0][1], ints=False)
        return reply.to_dict(ints=topic)


class Client(_Core):
    """A connection to skyd (blocking).

    Client(path=None, timeout=30.0, reconnect=True): path is the control
    socket, by default found as skyctl finds it ($XDG_RUNTIME_DIR/skyd/control
    if that socket exists, else /run/skyd/control). timeout bounds every
    call in seconds (None: forever); a request that times out drops the
    connection, since its reply could otherwise arrive as the next one's.
    With reconnect, a call that finds the connection closed (skyd
    restarted) connects again, renews the subscription, maps the new
    memory and sends its request; a request already sent when skyd went
    away raises ConnectionError (it may or may not have applied).

    The verbs: set, get, batch, status, subscribe, unsubscribe, sample,
    view_add, view_del, views, metar, sensor, sensor_list, sensor_events,
    commands, help, ping, quit (the close verb); request() sends any line.
    tables() and wait() read the shared memory; events() yields event
    lines; close() ends the connection from this side.
    A Client is not thread-safe: use one per thread.
    """

    def __init__(self, path=None, timeout=30.0, reconnect=True):
        self._core_init(path, timeout, reconnect)
        self._reconnecting = False
        self._connect(self.timeout)

    # Connection --------------------------------------------------------

    def _connect(self, timeout):
        s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM | socket.SOCK_CLOEXEC)
        try:
            s.settimeout(timeout)
            s.connect(self.path)
            self._sock = s
            self.protocol = w.parse_greeting(self._read_line(timeout))
        except BaseException:
            s.close()
            self._sock = None
            raise

    def close(self):
        """Closes the connection (skyd drops this connection's views and
        demand) and unmaps the shared memory; snapshots stay valid."""
        self._drop_connection()
        if self.region is not None:
            self.region.close()
            self.region = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __del__(self):
        try:
            self.close()
        except Exception:
            pass

    def _hung_up(self):
        """True when skyd closed its end (nothing more to read but EOF)."""
        if self._sock is None:
            return True
        p = select.poll()
        p.register(self._sock, select.POLLIN)
        if not p.poll(0):
            return False
        # Readable: queued bytes (events) or the end. A socket with a
        # timeout would wait in recv, whatever the flags: look without one.
        self._sock.setblocking(False)
        try:
            data = self._sock.recv(1, socket.MSG_PEEK)
        except BlockingIOError:
            return False
        except OSError:
            return True
        return data == b""

    def reconnect_now(self, timeout=None):
        """Drops the connection and connects again (retrying while skyd is
        not there, for up to timeout seconds, default the client's),
        renewing the subscription. Views this connection added are gone."""
        self._drop_connection()
        timeout = self.timeout if timeout is None else timeout
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            try:
                self._connect(self._left(deadline))
                break
            except (FileNotFoundError, ConnectionRefusedError):
                if deadline is not None and time.monotonic() + RECONNECT_INTERVAL_S > deadline:
                    raise
                time.sleep(RECONNECT_INTERVAL_S)
        before = None if self.region is None else self.region.identity
        if self._sub_tables or self._sub_events:
            self._reconnecting = True
            try:
                self._subscribe(self._sub_tables, self._sub_events)
            finally:
                self._reconnecting = False
        self._renumbered(before)

    def _ensure(self):
        if self._reconnecting or self._sock is not None and not self._hung_up():
            return
        if not self.reconnect:
            raise ConnectionResetError("skyd closed the connection")
        self.reconnect_now()

    @staticmethod
    def _left(deadline):
        if deadline is None:
            return None
        return max(deadline - time.monotonic(), 0.0)

    def _recv(self, timeout):
        """Reads what is there (waiting up to timeout) into the line reader;
        False on timeout, ConnectionResetError on EOF."""
        self._sock.settimeout(timeout)
        try:
            data, fds, _, _ = socket.recv_fds(self._sock, 65536, 16, socket.MSG_CMSG_CLOEXEC)
        except (socket.timeout, BlockingIOError):
            return False
        if not data:
            for fd in fds:
                os.close(fd)
            raise ConnectionResetError("skyd closed the connection")
        self._lines.feed(data, fds)
        return True

    def _read_line(self, timeout):
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            got = self._lines.next_line()
            if got is not None:
                return got
            if not self._recv(self._left(deadline)):
                raise TimeoutError("no reply from skyd within %s s" % timeout)

    def _read_reply(self, timeout, maps=False):
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            out = self._line_in(self._read_line(self._left(deadline)), maps)
            if out is not None:
                return out

    def _send(self, data):
        self._sock.settimeout(self.timeout)
        self._sock.sendall(data)

    def _exchange(self, data, n_replies=1, maps=False):
        """Sends data (request lines) and returns the n replies, reconnecting
        first when the connection was found closed; maps: the reply
        brings the shared memory (subscribe tables=)."""
        self._ensure()
        try:
            self._send(data)
        except (BrokenPipeError, ConnectionResetError):
            if not self.reconnect:
                raise
            self.reconnect_now()
            self._send(data)
        out = []
        try:
            for _ in range(n_replies):
                out.append(self._read_reply(self.timeout, maps))
        except TimeoutError:
            self._drop_connection()
            raise
        except (ConnectionResetError, BrokenPipeError) as e:
            self._drop_connection()
            raise ConnectionResetError("skyd went away before it answered (the request may "
                                       "or may not have applied): %s" % e) from None
        return out

    def _call(self, data, maps=False):
        reply = self._exchange(data, maps=maps)[0]
        if isinstance(reply, w.SkyError):
            raise reply
        self._note_generation(data, reply)
        return reply

    def request(self, verb, *words, **keys):
        """Sends one request and returns its Reply; SkyError on an ACK. verb
        may be a whole line ("get sun_elevation_deg") when no other argument
        is given."""
        if (" " in verb or "\t" in verb) and not words and not keys:
            if "\n" in verb or "\r" in verb:
                raise ValueError("a request is one line")
            data = (verb + "\n").encode("ascii")
            if len(data) > w.LINE_MAX:
                raise ValueError("request of %d bytes: at most %d" % (len(data), w.LINE_MAX))
        else:
            data = w.format_request(verb, *words, **keys)
        return self._call(data)

    # Verbs -------------------------------------------------------------

    def set(self, **keys):
        """Changes the sky (all keys or none); returns the generation that
        will show it. Values: numbers, r,g,b sequences, strings (quoted when
        they hold spaces), None for none, datetimes for utc."""
        if not keys:
            raise ValueError("set needs at least one key")
        return int(self.request("set", **keys)["generation"])

    def get(self, *keys, **args):
        """The state: get() every key (a dict), get("key") one value typed
        (float, tuple of floats, string, None for none), get("k1", "k2") a
        dict; get("sun"), get("moon"), get("times", date=..., utc_offset_min=...),
        get("weather"), get("sensor") their reports as dicts."""
        return self._typed_get(keys, args, self.request("get", *keys, **args))

    def batch(self):
        """A context manager: ``with c.batch() as b: b.set(...); b.set(...)``
        applies every line as one change and one computation when the block
        ends (b.generation is then the generation that shows it)."""
        return _SyncBatch(self)

    def _batch(self, lines):
        data = b"batch\n" + b"".join(lines) + b"end\n"
        first = self._exchange(data)[0]
        if isinstance(first, w.SkyError) and first.verb == "batch":
            # A refused batch opens none: every line after it was answered.
            for _ in range(len(lines) + 1):
                self._read_reply(self.timeout)
            raise first
        if isinstance(first, w.SkyError):
            raise first
        self._note_generation(data, first)
        return first

    def status(self):
        """skyd's status as a dict (counters int, times float, view: and
        sync lines parsed)."""
        return self.request("status").to_dict(ints=True, lists=("view",))

    def subscribe(self, *tables, events=None):
        """subscribe tables=... (names or "all") and/or events=0|1. With
        tables the shared memory is mapped (self.region) and the tables
        become this connection's demand; the list replaces the previous
        one. Returns the reply as a dict (its table: lines a list)."""
        names = table_names(tables) if tables else ()
        return self._subscribe(names, events)

    def _subscribe(self, names, events):
        reply = self._call(w.format_request("subscribe", **self._subscribe_args(names, events)),
                           maps=bool(names))
        if reply.map_error is not None:
            raise reply.map_error
        if names:
            self._sub_tables = names
        if events is not None:
            self._sub_events = bool(events)
        return reply.to_dict(ints=True, lists=("table",))

    def unsubscribe(self):
        """Ends this connection's subscription and samples' demand; the
        mapping stays until close()."""
        self.request("unsubscribe")
        self._sub_tables, self._sub_events = (), False

    def sample(self, what, **args):
        """The verb: sample("sky", el_deg=E, az_deg=A), sample("sun"),
        sample("ambient"): skyd samples its current slot (Sample)."""
        return Sample(what, self.request("sample", what, **args))

    def view_add(self, name, **keys):
        """view add name=NAME [altitude_km= east_km= north_km= yaw_deg=
        pitch_deg= roll_deg= vfov_deg= aspect= form=volume|panorama];
        returns the generation. The view lasts as long as this connection."""
        return int(self.request("view", "add", name=name, **keys)["generation"])

    def view_del(self, name):
        """view del name=NAME; returns the generation."""
        return int(self.request("view", "del", name=name)["generation"])

    def views(self):
        """view list: one dict per view."""
        return self.request("view", "list").to_dict(ints=True, lists=("view",)).get("view", [])

    def metar(self, report):
        """set metar="REPORT": the weather from a METAR; returns the reply as
        a dict (generation, metar_used, metar_ignored, metar_applied)."""
        return self.request("set", metar=report).to_dict(ints=True)

    def sensor(self):
        """get sensor: the light sensor's report (dict)."""
        return self.get("sensor")

    def sensor_list(self):
        """sensor list: the devices the running sensor knows (dicts)."""
        return self.request("sensor", "list").to_dict(ints=True, lists=("device",)).get(
            "device", [])

    def sensor_events(self, on=True):
        """sensor events=1|0: sensor: lines to this connection (events())."""
        self.request("sensor", events=1 if on else 0)

    def commands(self):
        """The verbs skyd knows."""
        return self.request("commands").getall("command")

    def help(self, verb=None):
        """help [VERB]: usage and help lines as a dict."""
        r = self.request("help", verb) if verb else self.request("help")
        return r.to_dict(ints=False)

    def ping(self):
        """ping: returns when skyd answered."""
        self.request("ping")

    def quit(self):
        """close: skyd answers OK and closes; then this client closes too."""
        try:
            self.request("close")
        finally:
            self.close()

    # Events ------------------------------------------------------------

    def events(self, timeout=None):
        """Yields Event objects as skyd sends them (``changed:``,
        ``layout:``, ``failed:``, ``sensor:``; ask with subscribe(events=True)
        or sensor_events()), and "reconnected" after a reconnection. Ends
        when none came for timeout seconds (None: never). A layout: event's
        new memory is already mapped when it is yielded."""
        while True:
            while self._replies.events:
                yield self._replies.events.popleft()
            try:
                if self._sock is None:
                    raise ConnectionResetError("not connected")
                if not self._pump(timeout):
                    return
            except ConnectionResetError:
                if not self.reconnect:
                    raise
                self.reconnect_now()
                yield w.Event("reconnected", {"generation": self.last_generation},
                              "reconnected")

    def _drain(self):
        """Handles the lines already received; True if there were any."""
        any_line = False
        while True:
            text = self._lines.next_line()
            if text is None:
                return any_line
            any_line = True
            if self._line_in(text) is not None:
                raise w.ProtocolError("a reply without a request: %r" % (text,))

    def _pump(self, timeout):
        """Handles lines between requests (events): those already received,
        else what arrives within timeout. False when nothing came."""
        if self._drain():
            return True
        if not self._recv(timeout):
            return False
        self._drain()
        return True

    # Shared memory -----------------------------------------------------

    def _need_region(self, names):
        names = table_names(names) if names else SKY_TABLE_NAMES
        if self.region is None or not set(names) <= set(self._sub_tables):
            self.subscribe(*sorted(set(names) | set(self._sub_tables),
                                   key=TABLE_NAMES.index))
        return names

    def tables(self, *names, at_least=None, timeout=None):
        """A Snapshot of the newest slot holding the named tables (default:
        all), subscribing to them first if this connection has not, and at
        least generation at_least (default: this client's last change, so
        that a set is seen by the next tables()). Waits for skyd to compute
        them, up to timeout seconds (default: the client's)."""
        names = self._need_region(names)
        floor = self.last_generation if at_least is None else at_least
        timeout = self.timeout if timeout is None else timeout
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            self._follow_layout(deadline)
            snap = self.region.snapshot()
            if snap.generation >= floor and set(names) <= set(snap.valid):
                return snap
            self.wait(snap.generation, timeout=self._left(deadline))

    def _follow_layout(self, deadline):
        """The region was superseded: read the socket until the new one,
        announced by a layout: line, is mapped."""
        while self.region.superseded():
            old = self.region
            while self.region is old:
                if not self._pump(self._left(deadline)):
                    raise TimeoutError("no new shared memory after a layout change")

    def wait(self, generation=None, timeout=None):
        """Blocks until a generation newer than generation (default: the one
        visible now) is published, and returns it; TimeoutError after
        timeout seconds (default: the client's). Sleeps on the shared
        memory's futex word (subscribing to every table first when this
        connection holds no region), follows layout changes and, with
        reconnect, a restart of skyd."""
        self._need_region(self._sub_tables)
        timeout = self.timeout if timeout is None else timeout
        deadline = None if timeout is None else time.monotonic() + timeout
        if generation is None:
            generation = self.region.visible_generation()[0] or 0
        while True:
            self._follow_layout(deadline)
            word = self.region.generation_word()
            vis, wake_ns = self.region.visible_generation()
            if vis is not None and vis > generation and not self.region.superseded():
                return vis
            left = self._left(deadline)
            if left == 0.0:
                raise TimeoutError("no generation after %d within %s s" % (generation, timeout))
            if self.reconnect and self._hung_up():
                before = self.region
                self.reconnect_now(timeout=left)
                if self.region is not before:
                    return self.region.visible_generation()[0] or 0
                continue
            step = 1.0 if left is None else min(left, 1.0)
            if wake_ns:
                step = min(step, max((wake_ns - time.time_ns()) / 1e9, 0.0))
            self.region.futex_wait(word, step)


class _SyncBatch(Batch):
    def __init__(self, client):
        super().__init__(client._batch)

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            self._done(self._send(self.lines))
        return False

