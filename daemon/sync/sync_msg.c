/* sync_msg.c - the replication messages: a sky state as versioned
 * key=value text, and the controller's presence; no I/O. */
#include "sync.h"

#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "simclock.h"
#include "state.h"

/* Longest line read or written; state values are far shorter. */
#define SYNC_LINE_MAX 512
/* Most body lines a message may have; a state has about 130. */
#define SYNC_BODY_LINES_MAX 512

#define NS_PER_S 1000000000ll

const char *sync_drop_name(enum sync_drop d)
{
	static const char *const names[] = { "none", "malformed", "version", "key",
					     "range", "controller", "stale" };
	return (unsigned)d < sizeof(names) / sizeof(names[0]) ? names[d] : "?";
}

static int id_char(char c)
{
	return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
	       c == '.' || c == '_' || c == '-';
}

int sync_id_valid(const char *text)
{
	size_t n = strnlen(text, SYNC_ID_MAX), part = 0;
	int slashes = 0;

	if (n == 0 || n >= SYNC_ID_MAX)
		return 0;
	for (size_t i = 0; i < n; i++) {
		if (text[i] == '/') {
			if (!part)
				return 0;
			slashes++;
			part = 0;
		} else if (id_char(text[i])) {
			part++;
		} else {
			return 0;
		}
	}
	return slashes == 2 && part > 0;
}

/* ---- writing ---- */

/* Text appended to a buffer; with buf NULL only the lines are counted. */
struct writer {
	char *buf;
	size_t size, len;
	uint32_t lines;
	int overflow;
	double utc_s;		/* the simulated time at the apply time, NAN: none */
	int bad_utc;
};

static void put(struct writer *w, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void put(struct writer *w, const char *fmt, ...)
{
	va_list ap;

	if (!w->buf || w->overflow)
		return;
	va_start(ap, fmt);
	int n = vsnprintf(w->buf + w->len, w->size - w->len, fmt, ap);
	va_end(ap);
	if (n < 0 || (size_t)n >= w->size - w->len)
		w->overflow = 1;
	else
		w->len += (size_t)n;
}

/* The flags of a key's row (enum state_key_flag); 0 for a name no row has. */
static unsigned key_flags(const char *key)
{
	const struct state_key *k = state_key_find(key);
	return k ? k->flags : 0;
}

/* Whether state_foreach's line key=value belongs in a message. A none
 * that state_set cannot read back stays out: a clock never set (the
 * receiver's stays unset too), the scale height of a profile that is not
 * a pure exponential (the layer keys carry it). */
static int line_sent(const char *key, const char *value)
{
	return !((key_flags(key) & STATE_KEY_NONE_UNSET) && strcmp(value, "none") == 0);
}

static void emit_body(void *ctx, const char *key, const char *value)
{
	struct writer *w = ctx;
	char t[64];

	if (!line_sent(key, value))
		return;
	w->lines++;
	/* The time at the apply instant, so that it means the same on every
	 * machine; state_foreach's is the time now. */
	if (key_flags(key) & STATE_KEY_NOW) {
		if (simclock_format_utc(w->utc_s, t, sizeof(t)) < 0)
			w->bad_utc = 1;
		value = t;
	}
	put(w, "%s=%s\n", key, value);
}

static void format_overrides(uint32_t bits, char *buf, size_t size)
{
	size_t o = 0;

	buf[0] = 0;
	for (uint32_t bit = 1; bit <= STATE_OVERRIDE_OZONE_ABSORPTION; bit <<= 1)
		if (bits & bit && o < size)
			o += (size_t)snprintf(buf + o, size - o, "%s%s", o ? "," : "", state_override_name(bit));
	if (!o)
		snprintf(buf, size, "none");
}

int sync_msg_encode(const struct sky_state *st, const struct sync_msg_header *h, char *buf,
		    size_t size, size_t *ret_len)
{
	struct writer w = { .buf = NULL };
	char overrides[160];
	double real_s, mono_s;

	if (!sync_id_valid(h->controller) || h->sequence == 0 || h->generation == 0 ||
	    h->apply_time_ns <= 0)
		return -EINVAL;
	simclock_read_clocks(&real_s, &mono_s);
	w.utc_s = state_clock_utc_s(st, mono_s + ((double)h->apply_time_ns / 1e9 - real_s));
	state_foreach_exact(st, emit_body, &w);
	uint32_t lines = w.lines;

	w = (struct writer){ .buf = buf, .size = size, .utc_s = w.utc_s };
	if (size == 0)
		return -ENOSPC;
	buf[0] = 0;
	format_overrides(st->weather.overridden, overrides, sizeof(overrides));
	put(&w, "skysync=%d\ncontroller=%s\nsequence=%" PRIu64 "\ngeneration=%" PRIu64
		"\napply_time_ns=%" PRId64 "\nlines=%" PRIu32 "\noverridden=%s\ncloud_factor=%.17g\n",
	    SYNC_FORMAT_VERSION, h->controller, h->sequence, h->generation, h->apply_time_ns, lines,
	    overrides, st->weather.cloud_factor);
	if (isnan(st->clouds.utc_s))
		put(&w, "cloud_placed_utc_s=none\n\n");
	else
		put(&w, "cloud_placed_utc_s=%.17g\n\n", st->clouds.utc_s);
	state_foreach_exact(st, emit_body, &w);
	if (w.bad_utc)
		return -ERANGE;		/* a simulated date outside years 0..9999 */
	if (w.overflow || w.len > SYNC_MSG_MAX)
		return -ENOSPC;
	*ret_len = w.len;
	return 0;
}

int sync_presence_encode(const struct sync_presence *p, char *buf, size_t size, size_t *ret_len)
{
	if (!sync_id_valid(p->controller))
		return -EINVAL;
	int n = snprintf(buf, size, "skysync=%d\ncontroller=%s\nonline=%d\n", SYNC_FORMAT_VERSION,
			 p->controller, p->online ? 1 : 0);
	if (n < 0 || (size_t)n >= size)
		return -ENOSPC;
	*ret_len = (size_t)n;
	return 0;
}

/* ---- reading ---- */

/* Writes the reason into why and returns d. */
static enum sync_drop drop(enum sync_drop d, char *why, size_t why_size, const char *fmt, ...)
	__attribute__((format(printf, 4, 5)));
static enum sync_drop drop(enum sync_drop d, char *why, size_t why_size, const char *fmt, ...)
{
	va_list ap;

	va_start(ap, fmt);
	vsnprintf(why, why_size, fmt, ap);
	va_end(ap);
	return d;
}

/* The lines of a payload, one at a time. */
struct cursor {
	const char *p, *end;
	unsigned line_no;
};

/* Every byte printable ASCII or a newline, the last one a newline. */
static enum sync_drop check_text(const unsigned char *p, size_t len, char *why, size_t why_size)
{
	if (len == 0)
		return drop(SYNC_DROP_MALFORMED, why, why_size, "empty");
	if (len > SYNC_MSG_MAX)
		return drop(SYNC_DROP_MALFORMED, why, why_size, "%zu bytes, more than %d", len,
			    SYNC_MSG_MAX);
	for (size_t i = 0; i < len; i++)
		if ((p[i] < 0x20 || p[i] > 0x7e) && p[i] != '\n')
			return drop(SYNC_DROP_MALFORMED, why, why_size,
				    "byte 0x%02x at offset %zu is not text", p[i], i);
	if (p[len - 1] != '\n')
		return drop(SYNC_DROP_MALFORMED, why, why_size,
			    "the last line has no newline (truncated?)");
	return SYNC_DROP_NONE;
}

/* The next line, terminated, into buf: 1, 0 at the end, -1 when longer
 * than the buffer. */
static int next_line(struct cursor *c, char *buf, size_t size)
{
	if (c->p >= c->end)
		return 0;
	const char *nl = memchr(c->p, '\n', (size_t)(c->end - c->p));
	size_t n = (size_t)(nl - c->p);
	c->line_no++;
	if (n >= size)
		return -1;
	memcpy(buf, c->p, n);
	buf[n] = 0;
	c->p = nl + 1;
	return 1;
}

static int key_valid(const char *k)
{
	if (!*k)
		return 0;
	for (; *k; k++)
		if (!((*k >= 'a' && *k <= 'z') || (*k >= '0' && *k <= '9') || *k == '_'))
			return 0;
	return 1;
}

/* A decimal number without sign, spaces or overflow. */
static int parse_u64(const char *s, uint64_t *ret)
{
	uint64_t v = 0;

	if (!*s || strlen(s) > 20)
		return -EINVAL;
	for (; *s; s++) {
		if (*s < '0' || *s > '9')
			return -EINVAL;
		unsigned d = (unsigned)(*s - '0');
		if (v > (UINT64_MAX - d) / 10)
			return -ERANGE;
		v = v * 10 + d;
	}
	*ret = v;
	return 0;
}

/* Splits "key=value" in place: 0 with *ret_value, or -EINVAL. */
static int split_pair(char *line, char **ret_value)
{
	char *eq = strchr(line, '=');
	if (!eq)
		return -EINVAL;
	*eq = 0;
	*ret_value = eq + 1;
	return key_valid(line) ? 0 : -EINVAL;
}

/* The first line, "skysync=VERSION". */
static enum sync_drop read_version(struct cursor *c, uint32_t *ret, char *why, size_t why_size)
{
	char line[SYNC_LINE_MAX], *v;
	uint64_t version;

	if (next_line(c, line, sizeof(line)) != 1 || split_pair(line, &v) < 0 ||
	    strcmp(line, "skysync") != 0)
		return drop(SYNC_DROP_MALFORMED, why, why_size, "not a skysync message");
	if (parse_u64(v, &version) < 0)
		return drop(SYNC_DROP_MALFORMED, why, why_size, "skysync=%s is not a version number", v);
	if (version != SYNC_FORMAT_VERSION)
		return drop(SYNC_DROP_VERSION, why, why_size,
			    "format version %" PRIu64 " (this skyd reads %d)", version,
			    SYNC_FORMAT_VERSION);
	*ret = (uint32_t)version;
	return SYNC_DROP_NONE;
}

enum {
	H_CONTROLLER, H_SEQUENCE, H_GENERATION, H_APPLY, H_LINES, H_OVERRIDDEN, H_CLOUD_FACTOR,
	H_ONLINE, H_CLOUD_PLACED, H_N
};
static const char *const header_keys[H_N] = { "controller", "sequence", "generation",
					      "apply_time_ns", "lines", "overridden",
					      "cloud_factor", "online", "cloud_placed_utc_s" };

/* Header lines up to a blank line or the end: the fields in want (a mask
 * of 1 << H_*) must all be there, once, those in optional at most once.
 * Unknown fields are skipped: a later revision of this version may add
 * some. */
struct header {
	char controller[SYNC_ID_MAX];
	uint64_t v[H_N];
	uint32_t overridden, seen;
	double cloud_factor, cloud_placed_utc_s;
};

/* "none" or a whole number of POSIX seconds within years 0..9999, as
 * %.17g wrote it. */
static int parse_placed(const char *v, double *ret)
{
	char *end;
	double t;

	if (strcmp(v, "none") == 0) {
		*ret = NAN;
		return 0;
	}
	if (!*v || strlen(v) > 32 || !((*v >= '0' && *v <= '9') || *v == '-'))
		return -EINVAL;
	t = strtod(v, &end);
	if (*end || !(t >= -62167219200.0 && t < 253402300800.0) || t != floor(t))
		return -EINVAL;
	*ret = t;
	return 0;
}

/* "none" or a comma list of override names (state_override_name), each once. */
static int parse_overrides(const char *v, uint32_t *ret)
{
	uint32_t bits = 0;

	if (strcmp(v, "none") == 0) {
		*ret = 0;
		return 0;
	}
	while (*v) {
		size_t n = strcspn(v, ",");
		uint32_t bit = 1;
		while (bit <= STATE_OVERRIDE_OZONE_ABSORPTION &&
		       (strlen(state_override_name(bit)) != n || strncmp(state_override_name(bit), v, n) != 0))
			bit <<= 1;
		if (bit > STATE_OVERRIDE_OZONE_ABSORPTION || bits & bit)
			return -EINVAL;
		bits |= bit;
		v += n;
		if (*v == ',' && *++v == 0)
			return -EINVAL;
	}
	*ret = bits;
	return bits ? 0 : -EINVAL;
}

/* A factor in [0, 1], as %.17g wrote it. */
static int parse_factor(const char *v, double *ret)
{
	char *end;
	double f;

	if (!*v || strlen(v) > 32 || !((*v >= '0' && *v <= '9') || *v == '.'))
		return -EINVAL;
	f = strtod(v, &end);
	if (*end || !(f >= 0.0 && f <= 1.0))
		return -EINVAL;
	*ret = f;
	return 0;
}

static enum sync_drop read_field(struct header *h, unsigned idx, const char *v, char *why,
				 size_t why_size)
{
	if (idx == H_CONTROLLER) {
		if (!sync_id_valid(v))
			return drop(SYNC_DROP_MALFORMED, why, why_size, "controller: not a controller id");
		snprintf(h->controller, sizeof(h->controller), "%s", v);
		return SYNC_DROP_NONE;
	}
	if (idx == H_OVERRIDDEN && parse_overrides(v, &h->overridden) < 0)
		return drop(SYNC_DROP_MALFORMED, why, why_size,
			    "overridden: not none or a list of raw coefficient keys");
	if (idx == H_CLOUD_FACTOR && parse_factor(v, &h->cloud_factor) < 0)
		return drop(SYNC_DROP_RANGE, why, why_size, "cloud_factor: not a number in [0, 1]");
	if (idx == H_CLOUD_PLACED && parse_placed(v, &h->cloud_placed_utc_s) < 0)
		return drop(SYNC_DROP_RANGE, why, why_size,
			    "cloud_placed_utc_s: not none or a whole second of years 0..9999");
	if (idx == H_OVERRIDDEN || idx == H_CLOUD_FACTOR || idx == H_CLOUD_PLACED)
		return SYNC_DROP_NONE;
	if (parse_u64(v, &h->v[idx]) < 0)
		return drop(SYNC_DROP_MALFORMED, why, why_size, "%s=%s is not a number",
			    header_keys[idx], v);
	return SYNC_DROP_NONE;
}

static enum sync_drop read_header(struct cursor *c, unsigned want, unsigned optional,
				  struct header *h, char *why, size_t why_size)
{
	char line[SYNC_LINE_MAX], *v;
	unsigned seen = 0;
	int r;

	while ((r = next_line(c, line, sizeof(line))) == 1 && line[0]) {
		if (split_pair(line, &v) < 0)
			return drop(SYNC_DROP_MALFORMED, why, why_size,
				    "header line %u is not key=value", c->line_no);
		for (unsigned i = 0; i < H_N; i++) {
			if (!((want | optional) & (1u << i)) || strcmp(line, header_keys[i]) != 0)
				continue;
			if (seen & (1u << i))
				return drop(SYNC_DROP_MALFORMED, why, why_size, "%s twice", line);
			seen |= 1u << i;
			enum sync_drop d = read_field(h, i, v, why, why_size);
			if (d)
				return d;
		}
	}
	if (r < 0)
		return drop(SYNC_DROP_MALFORMED, why, why_size, "line %u is too long", c->line_no);
	for (unsigned i = 0; i < H_N; i++)
		if ((want & ~seen) & (1u << i))
			return drop(SYNC_DROP_MALFORMED, why, why_size, "no %s in the header",
				    header_keys[i]);
	h->seen = seen;
	return SYNC_DROP_NONE;
}

/* The keys a message named, to check it against the state it made. */
struct keyset {
	char (*names)[64];
	unsigned n;
	const char *missing;
	unsigned expected;
	double utc_s;
};

static int keyset_has(const struct keyset *ks, const char *key)
{
	for (unsigned i = 0; i < ks->n; i++)
		if (strcmp(ks->names[i], key) == 0)
			return 1;
	return 0;
}

static void keyset_expect(void *ctx, const char *key, const char *value)
{
	struct keyset *ks = ctx;

	if (!line_sent(key, value))
		return;
	ks->expected++;
	if (!ks->missing && !keyset_has(ks, key))
		ks->missing = key;
}

static enum sync_drop refused(int r, const char *err, char *why, size_t why_size)
{
	return drop(r == -ENOENT ? SYNC_DROP_KEY : SYNC_DROP_RANGE, why, why_size, "%s", err);
}

/* The lines set after every other (STATE_KEY_LAST: the light modes). */
#define SYNC_LAST_MAX 4
struct last_lines {
	unsigned n;
	char pair[SYNC_LAST_MAX][SYNC_LINE_MAX];
};

/* One body line onto the candidate. The light modes wait in *last until
 * every other key is set: keys such as sun_elevation_deg or lat_deg hand
 * a light to the user or the clock as a side effect. */
static enum sync_drop body_line(struct sky_state *st, char *line, struct keyset *ks,
				struct last_lines *last, double *utc_s, char *why, size_t why_size)
{
	char pair[SYNC_LINE_MAX], err[256], *v;

	snprintf(pair, sizeof(pair), "%s", line);
	if (split_pair(line, &v) < 0 || strlen(line) >= sizeof(ks->names[0]))
		return drop(SYNC_DROP_MALFORMED, why, why_size, "body line is not key=value");
	if (keyset_has(ks, line))
		return drop(SYNC_DROP_MALFORMED, why, why_size, "%s twice", line);
	snprintf(ks->names[ks->n++], sizeof(ks->names[0]), "%s", line);
	unsigned flags = key_flags(line);
	if (flags & STATE_KEY_LAST) {
		if (last->n == SYNC_LAST_MAX)
			return drop(SYNC_DROP_MALFORMED, why, why_size, "more than %d mode lines",
				    SYNC_LAST_MAX);
		snprintf(last->pair[last->n++], SYNC_LINE_MAX, "%s", pair);
		return SYNC_DROP_NONE;
	}
	if ((flags & STATE_KEY_NOW) && simclock_parse_utc(v, utc_s) < 0)
		return drop(SYNC_DROP_RANGE, why, why_size, "%s: '%s' is not an ISO 8601 UTC time",
			    line, v);
	/* A value the candidate already shows, bit for bit, is not set again:
	 * setting a raw constituent key pins it against the weather. */
	char cur[256];
	if (!(flags & STATE_KEY_NOW) && state_get_exact(st, line, cur, sizeof(cur)) == 0 &&
	    strcmp(cur, v) == 0)
		return SYNC_DROP_NONE;
	int r = state_set_pair(st, pair, NULL, err, sizeof(err));
	return r < 0 ? refused(r, err, why, why_size) : SYNC_DROP_NONE;
}

static enum sync_drop read_body(struct cursor *c, uint64_t lines, struct sky_state *st,
				struct keyset *ks, char *why, size_t why_size)
{
	char line[SYNC_LINE_MAX], err[256];
	struct last_lines last = { .n = 0 };
	uint64_t n = 0;
	int r;

	state_default(st);
	while ((r = next_line(c, line, sizeof(line))) == 1) {
		if (++n > lines || n > SYNC_BODY_LINES_MAX)
			return drop(SYNC_DROP_MALFORMED, why, why_size,
				    "more lines than the header's %" PRIu64, lines);
		enum sync_drop d = body_line(st, line, ks, &last, &ks->utc_s, why, why_size);
		if (d)
			return d;
	}
	if (r < 0)
		return drop(SYNC_DROP_MALFORMED, why, why_size, "line %u is too long", c->line_no);
	if (n != lines)
		return drop(SYNC_DROP_MALFORMED, why, why_size,
			    "%" PRIu64 " lines where the header says %" PRIu64, n, lines);
	for (unsigned i = 0; i < last.n; i++)
		if ((r = state_set_pair(st, last.pair[i], NULL, err, sizeof(err))) < 0)
			return refused(r, err, why, why_size);
	return SYNC_DROP_NONE;
}

/* The simulated clock runs on from the time the message gives for its
 * apply instant, on the receiver's monotonic clock; a message without a
 * time leaves the clock unset, as the sender's was. */
static void anchor_clock(struct sky_state *st, double utc_at_apply_s, int64_t apply_time_ns,
			 double real_s, double mono_s)
{
	struct state_clock *c = &st->clock;

	if (isnan(utc_at_apply_s)) {
		c->anchor_utc_s = NAN;
		c->anchor_mono_s = 0.0;
		return;
	}
	c->anchor_utc_s = utc_at_apply_s + c->rate * (real_s - (double)apply_time_ns / 1e9);
	c->anchor_mono_s = mono_s;
}

enum sync_drop sync_msg_decode(const void *payload, size_t len, struct sync_msg_header *ret_header,
			       struct sky_state *ret_state, char *why, size_t why_size)
{
	char names[SYNC_BODY_LINES_MAX][64];
	struct cursor c = { payload, (const char *)payload + len, 0 };
	struct keyset ks = { .names = names, .utc_s = NAN };
	struct header h = { .controller = "" };
	char err[256];
	double real_s, mono_s;
	enum sync_drop d;

	memset(ret_header, 0, sizeof(*ret_header));
	if ((d = check_text(payload, len, why, why_size)) ||
	    (d = read_version(&c, &ret_header->version, why, why_size)) ||
	    (d = read_header(&c, 1u << H_CONTROLLER | 1u << H_SEQUENCE | 1u << H_GENERATION |
				     1u << H_APPLY | 1u << H_LINES | 1u << H_OVERRIDDEN |
				     1u << H_CLOUD_FACTOR, 1u << H_CLOUD_PLACED, &h, why, why_size)))
		return d;
	if (h.v[H_SEQUENCE] == 0 || h.v[H_GENERATION] == 0 || h.v[H_APPLY] == 0 ||
	    h.v[H_APPLY] > INT64_MAX)
		return drop(SYNC_DROP_MALFORMED, why, why_size,
			    "sequence, generation and apply_time_ns must be positive");
	snprintf(ret_header->controller, sizeof(ret_header->controller), "%s", h.controller);
	ret_header->sequence = h.v[H_SEQUENCE];
	ret_header->generation = h.v[H_GENERATION];
	ret_header->apply_time_ns = (int64_t)h.v[H_APPLY];
	ret_header->cloud_placed_sent = (h.seen >> H_CLOUD_PLACED) & 1u;
	ret_header->cloud_placed_utc_s = ret_header->cloud_placed_sent ? h.cloud_placed_utc_s : NAN;

	if ((d = read_body(&c, h.v[H_LINES], ret_state, &ks, why, why_size)))
		return d;
	/* What no key says: which raw keys win over the weather (the order in
	 * which they were set), and a cloud factor a light sensor set, which
	 * cloud_oktas gives back only to within its last bits. */
	ret_state->weather.overridden = h.overridden;
	ret_state->weather.cloud_factor = h.cloud_factor;
	simclock_read_clocks(&real_s, &mono_s);
	anchor_clock(ret_state, ks.utc_s, ret_header->apply_time_ns, real_s, mono_s);
	/* Every key the state has, nothing else: a message that leaves one
	 * out would leave that key at its default here and not there. */
	state_foreach_exact(ret_state, keyset_expect, &ks);
	if (ks.missing)
		return drop(SYNC_DROP_MALFORMED, why, why_size, "no %s", ks.missing);
	if (ks.expected != ks.n)
		return drop(SYNC_DROP_MALFORMED, why, why_size, "%u keys where the state has %u",
			    ks.n, ks.expected);
	int r = state_validate(ret_state, 0, err, sizeof(err));
	if (r < 0)
		return refused(r, err, why, why_size);
	double ahead_ns = (double)ret_header->apply_time_ns - real_s * 1e9;
	if (ahead_ns > (double)SYNC_APPLY_AHEAD_MAX_NS)
		return drop(SYNC_DROP_RANGE, why, why_size, "apply time %.0f s ahead of this clock",
			    ahead_ns / 1e9);
	return SYNC_DROP_NONE;
}

enum sync_drop sync_presence_decode(const void *payload, size_t len, struct sync_presence *ret,
				    char *why, size_t why_size)
{
	struct cursor c = { payload, (const char *)payload + len, 0 };
	struct header h = { .controller = "" };
	uint32_t version;
	enum sync_drop d;

	memset(ret, 0, sizeof(*ret));
	if (len == 0)
		return SYNC_DROP_NONE;
	if ((d = check_text(payload, len, why, why_size)) ||
	    (d = read_version(&c, &version, why, why_size)) ||
	    (d = read_header(&c, 1u << H_CONTROLLER | 1u << H_ONLINE, 0, &h, why, why_size)))
		return d;
	if (c.p != c.end)
		return drop(SYNC_DROP_MALFORMED, why, why_size, "a body after the presence");
	if (h.v[H_ONLINE] > 1)
		return drop(SYNC_DROP_MALFORMED, why, why_size, "online must be 0 or 1");
	snprintf(ret->controller, sizeof(ret->controller), "%s", h.controller);
	ret->online = (int)h.v[H_ONLINE];
	return SYNC_DROP_NONE;
}
