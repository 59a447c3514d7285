"""The text protocol without I/O: request lines, replies, ACKs, events.

Both clients (blocking and asyncio) feed the bytes and file descriptors they
receive into a LineReader and a ReplyReader and send what format_request
makes; nothing here touches a socket, so the two cannot drift apart.
proto/PROTOCOL.md is the reference for every rule followed here.
"""

import collections
import datetime
import enum
import math
import numbers
import re

PROTOCOL_VERSION = "7.1"
LINE_MAX = 4096          # bytes per request line, newline included
ARGS_MAX = 128           # arguments per request line
EVENT_KINDS = ("changed", "layout", "failed", "sensor")

_KEY = re.compile(r"[a-z0-9_]+\Z")
_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*(?:[eE][-+]?\d+)?|\.\d+(?:[eE][-+]?\d+)?|inf|nan)\Z")
_INTEGER = re.compile(r"[-+]?\d+\Z")
_WORD = re.compile(r"[a-z][a-z0-9_]*\Z")
_FIELD = re.compile(r"[a-z][a-z0-9_]*=\S*\Z")
# "line 2: key: message" (a batch's end) or "key: message".
_ACK = re.compile(r"ACK \[(\d+)\] \{([^}]*)\} ?(.*)\Z")
_ACK_LINE = re.compile(r"line (\d+): (.*)\Z")
_ACK_KEY = re.compile(r"([a-z0-9_]+): ")


class Ack(enum.IntEnum):
    """The ACK codes of PROTOCOL.md ("ACK codes")."""

    SYNTAX = 1
    ARG = 2
    PERMISSION = 4
    UNKNOWN = 5
    NO_EXIST = 50
    RANGE = 51
    LIMIT = 52
    TOO_LONG = 53
    STATE = 54
    ENGINE = 60


class SkyError(Exception):
    """skyd refused a request: its ``ACK [code] {verb} message`` line.

    code      the ACK code (an int; compare with skyd.Ack.RANGE and friends)
    name      the code's name in lower case ("range"), or "unknown_code"
    verb      the verb skyd names in braces ("set", "end", "connect")
    key       the key the message starts with ("sun_elevation_deg"), else None
    message   the text after the braces, as skyd wrote it
    line      for a refused batch, the line of the batch at fault, else None

    A refused request changed nothing: the state, the tables and the
    connection are as they were (PROTOCOL.md, "Lines").
    """

    def __init__(self, code, verb, message, key=None, line=None):
        self.code = int(code)
        self.verb = verb
        self.message = message
        self.key = key
        self.line = line
        super().__init__(code, verb, message)

    @property
    def name(self):
        try:
            return Ack(self.code).name.lower()
        except ValueError:
            return "unknown_code"

    def __str__(self):
        return "ACK [%d] {%s} %s" % (self.code, self.verb, self.message)

    def __repr__(self):
        return "SkyError(code=%d, verb=%r, key=%r, message=%r)" % (
            self.code, self.verb, self.key, self.message)


class ProtocolError(Exception):
    """skyd said something this package cannot read (or it is not skyd)."""


def parse_ack(text):
    """SkyError from an ``ACK [code] {verb} message`` line."""
    m = _ACK.match(text)
    if not m:
        raise ProtocolError("not an ACK line: %r" % text)
    code, verb, message = int(m.group(1)), m.group(2), m.group(3)
    rest, line = message, None
    lm = _ACK_LINE.match(rest)
    if lm:
        line, rest = int(lm.group(1)), lm.group(2)
    km = _ACK_KEY.match(rest)
    return SkyError(code, verb, message, key=km.group(1) if km else None, line=line)


def _number(text, ints):
    if ints and _INTEGER.match(text):
        return int(text)
    return float(text)


def parse_value(text, ints=True):
    """A reply's value typed: a number (int for an integer literal when ints,
    else float), a comma list of numbers as a tuple, "none" as None, any
    other comma list as a tuple of strings, anything else the string."""
    t = text.strip()
    if t == "none":
        return None
    if _NUMBER.match(t):
        return _number(t, ints)
    if "," in t and " " not in t:
        parts = t.split(",")
        if all(_NUMBER.match(p) for p in parts):
            return tuple(_number(p, ints) for p in parts)
        if all(_WORD.match(p) for p in parts):
            return tuple(parts)
    return t


def parse_fields(text, ints=True):
    """``name=left index=0 valid=1`` as a dict of typed values."""
    out = {}
    for word in text.split():
        k, sep, v = word.partition("=")
        out[k] = parse_value(v, ints) if sep else True
    return out


def _format_scalar(v):
    if isinstance(v, bool):
        return "1" if v else "0"
    if isinstance(v, numbers.Integral):
        return str(int(v))
    if isinstance(v, numbers.Real):
        f = float(v)
        # skyd refuses what is not finite (ACK [2]); say it in its words.
        if math.isnan(f):
            return "nan"
        if math.isinf(f):
            return "inf" if f > 0 else "-inf"
        return repr(f)
    raise TypeError("not a number: %r" % (v,))


def _format_time(v):
    if isinstance(v, datetime.datetime):
        if v.tzinfo is None:
            raise ValueError("a naive datetime is ambiguous: give it a tzinfo (UTC)")
        v = v.astimezone(datetime.timezone.utc)
        text = v.strftime("%Y-%m-%dT%H:%M:%S")
        if v.microsecond:
            text += (".%06d" % v.microsecond).rstrip("0")
        return text + "Z"
    return v.strftime("%Y-%m-%d")


def format_value(v):
    """A Python value as the protocol writes it: numbers in the C locale,
    sequences as r,g,b, None as none, booleans 1/0, datetimes as ISO 8601
    UTC, strings with spaces quoted. ValueError for what no line can hold."""
    if v is None:
        return "none"
    if isinstance(v, (datetime.datetime, datetime.date)):
        return _format_time(v)
    if isinstance(v, str):
        if '"' in v or any(ord(ch) < 32 and ch != "\t" or ord(ch) > 126 for ch in v):
            raise ValueError("%r: a value cannot hold '\"', control or non-ASCII characters" % v)
        return '"%s"' % v if (" " in v or "\t" in v or not v) else v
    if isinstance(v, (bool, numbers.Number)):
        return _format_scalar(v)
    try:
        items = list(v)
    except TypeError:
        raise TypeError("cannot send %r" % (v,)) from None
    if not items:
        raise ValueError("an empty sequence has no value")
    return ",".join(_format_scalar(x) for x in items)


def check_key(key):
    if not isinstance(key, str) or not _KEY.match(key):
        raise ValueError("%r: a key is lower-case letters, digits and _" % (key,))
    return key


def format_request(verb, *words, **keys):
    """One request line (bytes, newline included): the verb, bare words,
    then key=value arguments in the order given."""
    check_key(verb)
    parts = [verb]
    for w in words:
        parts.append(check_key(w))
    for k, v in keys.items():
        parts.append("%s=%s" % (check_key(k), format_value(v)))
    if len(parts) - 1 > ARGS_MAX:
        raise ValueError("%d arguments: at most %d" % (len(parts) - 1, ARGS_MAX))
    line = (" ".join(parts) + "\n").encode("ascii")
    if len(line) > LINE_MAX:
        raise ValueError("request of %d bytes: at most %d" % (len(line), LINE_MAX))
    return line


class Reply:
    """One OK reply: its ``key: value`` lines in order.

    reply["key"] is the first value as skyd wrote it (a string),
    reply.value("key") the same typed, reply.getall("key") every value of a
    repeated key (``table:``, ``view:``, ``command:`` lines).
    """

    def __init__(self, pairs):
        self.pairs = list(pairs)

    def __getitem__(self, key):
        for k, v in self.pairs:
            if k == key:
                return v
        raise KeyError(key)

    def __contains__(self, key):
        return any(k == key for k, _ in self.pairs)

    def get(self, key, default=None):
        try:
            return self[key]
        except KeyError:
            return default

    def value(self, key, default=None, ints=True):
        return parse_value(self[key], ints) if key in self else default

    def getall(self, key):
        return [v for k, v in self.pairs if k == key]

    def to_dict(self, ints=True, lists=()):
        """Typed values by key (parse_value, or parse_fields for a value made
        of k=v words such as ``view: name=left index=0``); a key that
        repeats, or is named in lists, gives a list of them."""
        counts = collections.Counter(k for k, _ in self.pairs)
        out = {}
        for k, v in self.pairs:
            val = typed(v, ints)
            if counts[k] > 1 or k in lists:
                out.setdefault(k, []).append(val)
            else:
                out[k] = val
        return out

    def __repr__(self):
        return "Reply(%r)" % (self.pairs,)


def typed(v, ints=True):
    """A reply value as parse_fields reads it when every word is k=v, else
    as parse_value does."""
    words = v.split()
    if words and all(_FIELD.match(w) for w in words):
        return parse_fields(v, ints)
    return parse_value(v, ints)


class Event:
    """A line skyd sends between replies: ``changed:``, ``layout:``,
    ``failed:`` or ``sensor:`` (PROTOCOL.md, subscribe and sensor), or
    ``reconnected`` when the client came back to a restarted skyd.

    kind        "changed", "layout", "failed", "sensor" or "reconnected"
    fields      the line's key=value words, typed (dict)
    generation  fields["generation"] (int), or None
    tables      the tables a changed: line names, as a tuple
    line        the line as it came
    """

    def __init__(self, kind, fields, line):
        self.kind = kind
        self.fields = fields
        self.line = line

    @property
    def generation(self):
        g = self.fields.get("generation")
        return int(g) if isinstance(g, (int, float)) else None

    @property
    def tables(self):
        t = self.fields.get("tables")
        if t is None or t == "none":
            return ()
        return (t,) if isinstance(t, str) else tuple(t)

    def __repr__(self):
        return "Event(%r, %r)" % (self.kind, self.fields)


def parse_event(text):
    kind, _, rest = text.partition(":")
    return Event(kind, parse_fields(rest), text)


def is_event(text):
    kind, sep, _ = text.partition(":")
    return bool(sep) and kind in EVENT_KINDS


class LineReader:
    """Splits received bytes into lines and queues the file descriptors that
    came with them. skyd sends a descriptor with the first byte of the line
    that needs it (a ``layout:`` line, a subscribe's reply), and only those
    lines carry one, so the line being handled takes the oldest (as libsky
    does): the kernel may hand a descriptor over together with bytes that
    precede its line, never after them."""

    BUFFER_MAX = 1 << 22

    def __init__(self):
        self._buf = bytearray()
        self._fds = collections.deque()

    def feed(self, data, fds=()):
        self._fds.extend(fds)
        self._buf += data
        if len(self._buf) > self.BUFFER_MAX and b"\n" not in self._buf:
            raise ProtocolError("a line of over %d bytes from skyd" % self.BUFFER_MAX)

    def next_line(self):
        """The next complete line (without its newline), or None."""
        i = self._buf.find(b"\n")
        if i < 0:
            return None
        text = self._buf[:i].decode("utf-8", "replace").rstrip("\r")
        del self._buf[:i + 1]
        return text

    def take_fd(self):
        """The oldest descriptor received and not yet taken, or None."""
        return self._fds.popleft() if self._fds else None

    def take_fds(self):
        """Every descriptor still held (to close them when the connection ends)."""
        fds = list(self._fds)
        self._fds.clear()
        return fds


class ReplyReader:
    """Assembles replies from lines: ``key: value`` lines, then ``OK`` or an
    ACK line; event lines go to the events queue wherever they arrive."""

    def __init__(self, events_max=None):
        self.events = collections.deque(maxlen=events_max)
        self._pairs = []

    def push(self, text):
        """Takes one line; returns the Event it was, or a Reply or SkyError
        when it completed a reply, else None."""
        if not text:
            return None
        if is_event(text):
            ev = parse_event(text)
            self.events.append(ev)
            return ev
        if text == "OK":
            r = Reply(self._pairs)
            self._pairs = []
            return r
        if text.startswith("ACK "):
            self._pairs = []
            return parse_ack(text)
        k, sep, v = text.partition(": ")
        if not sep:
            k, sep, v = text.partition(":")
        if not sep:
            raise ProtocolError("not a reply line: %r" % text)
        self._pairs.append((k, v))
        return None


def parse_greeting(text):
    """The protocol version of ``OK skyd 5``; ``ACK [52] {connect}`` raises."""
    if text.startswith("ACK "):
        raise parse_ack(text)
    m = re.match(r"OK skyd (\S+)\Z", text)
    if not m:
        raise ProtocolError("not skyd's greeting: %r" % text)
    if m.group(1).split(".")[0] != PROTOCOL_VERSION.split(".")[0]:
        raise ProtocolError("skyd speaks protocol %s; this package speaks %s"
                            % (m.group(1), PROTOCOL_VERSION))
    return m.group(1)
