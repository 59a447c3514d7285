/* test_daemon_fuzz.c - a fuzzer of skyd through its socket: a seeded
 * generator drives a real skyd (built with the sanitizers in CI's
 * sanitizer pass) with requests of every verb of its command table
 * (`commands`) and values for every key it lists (`skyd --list-keys`),
 * mostly valid, some mutated, over several connections that subscribe,
 * add views, open batches, stall, and close at random points: before,
 * during and after their replies, with a FIN or a reset, and with skyd
 * stopped (SIGSTOP) so that it finds the lines and the hang-up together,
 * as test_daemon_client_vanish does. It fails when skyd dies, stops
 * answering `ping` on a connection of its own, exits other than cleanly
 * (LeakSanitizer fails the exit), or a sanitizer writes a report.
 *
 * A run is rounds, each a fresh skyd and one seed: --seed S is the first
 * round's, the next rounds take S+1, S+2, ... until --seconds have passed
 * or --rounds are done, each round at most --steps steps; the run stops
 * at the first failed round, or goes on with --keep-going (a long run by
 * hand, its failures counted at the end). The requests,
 * their order, the connections and where they close follow from the seed
 * alone; how much skyd has answered at each point is up to timing. A
 * failure prints the seed, the step, the last actions, skyd's log and the
 * command that runs that round again. */
#include <dirent.h>
#include <math.h>
#include <stdarg.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <time.h>

#include "daemon_harness.h"
#include "skyproto.h"
#include "test.h"

#define FUZZ_CONNS 6		/* connections at once, besides the probe */
#define FUZZ_KEYS_MAX 192
#define FUZZ_VERBS_MAX 32
#define FUZZ_NAMES_MAX 12
#define FUZZ_TRAIL 24		/* actions kept for the report */
#define FUZZ_REQ_MAX 8192
#define FUZZ_PING_EVERY 64	/* steps between pings of the probe */

/* ---- the seeded generator ---- */

struct rng {
	uint64_t s;
};

static uint64_t rng_next(struct rng *r)	/* splitmix64 */
{
	uint64_t z = (r->s += 0x9e3779b97f4a7c15ull);
	z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
	z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
	return z ^ (z >> 31);
}

static unsigned rng_below(struct rng *r, unsigned n)
{
	return n ? (unsigned)(rng_next(r) % n) : 0;
}

static double rng_unit(struct rng *r)
{
	return (double)(rng_next(r) >> 11) / 9007199254740992.0;
}

static int rng_chance(struct rng *r, double p)
{
	return rng_unit(r) < p;
}

/* ---- the keys, as skyd lists them ---- */

enum range_kind { R_INTERVAL, R_ATLEAST, R_ATMOST, R_FINITE, R_NAMES, R_TIME, R_METAR };

struct key {
	char name[48];
	enum range_kind kind;
	double lo, hi;
	int has_auto;		/* "auto or ..." */
	int is_vector;		/* its default is r,g,b */
	int is_count;		/* texels, steps, slices, directions: whole and kept small */
	char names[FUZZ_NAMES_MAX][32];
	int n_names;
};

/* Sizes and step counts are drawn up to this: the tables stay small, so
 * that a round computes many of them under the sanitizers. */
#define FUZZ_COUNT_MAX 48.0

/* Keys left out, each for its cost: quality sets every size to a preset's
 * (seconds of computation a change under the sanitizers). */
static const char *const skipped_keys[] = { "quality" };

static const char *const metars[] = {
	"EGLL 241250Z 24012KT 9999 FEW030 SCT250 18/09 Q1021",
	"KJFK 121751Z 31012G20KT 10SM FEW050 SCT250 22/08 A3002 RMK AO2",
	"SPECI KORD 031422Z 05018G29KT 1/2SM R28L/2600FT +SN FZFG VV004 M04/M05 A2965",
	"LFPG 091030Z VRB02KT 0300 R27L/0450N FG VV001 08/08 Q1030 NOSIG",
	"METAR EGLL 121320Z NIL",
	"OMDB 150600Z 32015KT 2000 SA NSC 35/10 Q1005",
};

struct fuzz {
	struct rng rng;
	struct key keys[FUZZ_KEYS_MAX];
	int n_keys;
	char verbs[FUZZ_VERBS_MAX][24];
	int n_verbs;
	uint64_t seed;
	int step;
	char trail[FUZZ_TRAIL][160];
	int n_trail;
	struct daemon d;
	struct conn probe;
	struct fconn {
		int fd;			/* -1: free */
		int stalled;		/* never read again: skyd's bound on its queue */
	} conns[FUZZ_CONNS];
	unsigned long stats[8];
};

enum { S_REQUESTS, S_CLOSES, S_RESETS, S_VANISHES, S_FDS, S_MUTATED, S_PINGS };

/* What the regions received say, read so that no read is optimised out. */
static volatile uint32_t seen_generation;

static double fuzz_now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static void note(struct fuzz *f, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void note(struct fuzz *f, const char *fmt, ...)
{
	va_list ap;
	char *t = f->trail[f->n_trail++ % FUZZ_TRAIL];

	va_start(ap, fmt);
	int n = snprintf(t, sizeof(f->trail[0]), "%d: ", f->step);
	vsnprintf(t + n, sizeof(f->trail[0]) - (size_t)n, fmt, ap);
	va_end(ap);
}

/* "[a, b]", "(a, b)", ">= a", "<= a", "finite", "a, b, c", "auto or ...". */
static void key_parse_range(struct key *k, const char *range)
{
	if (!strncmp(range, "auto or ", 8)) {
		k->has_auto = 1;
		range += 8;
	}
	if (!strncmp(range, "now or", 6)) {
		k->kind = R_TIME;
	} else if (strstr(range, "METAR")) {
		k->kind = R_METAR;
	} else if (range[0] == '[' || range[0] == '(') {
		k->kind = R_INTERVAL;
		if (sscanf(range + 1, "%lf, %lf", &k->lo, &k->hi) != 2)
			k->lo = 0, k->hi = 1;
		/* An open end is stepped inside: the values drawn are valid. */
		if (range[0] == '(')
			k->lo += fabs(k->hi - k->lo) * 1e-6;
		if (strchr(range, ')'))
			k->hi -= fabs(k->hi - k->lo) * 1e-6;
	} else if (range[0] == '>') {
		k->kind = R_ATLEAST;
		k->lo = atof(range + (range[1] == '=' ? 2 : 1)) + (range[1] == '=' ? 0 : 1e-6);
	} else if (range[0] == '<') {
		k->kind = R_ATMOST;
		k->hi = atof(range + 2);
	} else if (!strcmp(range, "finite")) {
		k->kind = R_FINITE;
	} else {
		k->kind = R_NAMES;
		char copy[256], *save = NULL;
		snprintf(copy, sizeof(copy), "%s", range);
		for (char *t = strtok_r(copy, ", ", &save); t && k->n_names < FUZZ_NAMES_MAX;
		     t = strtok_r(NULL, ", ", &save)) {
			/* bus:PORTS, serial:TEXT: a value of that form */
			char *colon = strchr(t, ':');
			if (colon)
				snprintf(colon + 1, 8, "%s", !strcmp(colon + 1, "PORTS") ? "1-2" : "light");
			snprintf(k->names[k->n_names++], sizeof(k->names[0]), "%s", t);
		}
	}
}

/* skyd --list-keys: name, unit, range, default, tables, text; tabs. */
static int load_keys(struct fuzz *f)
{
	char line[1024];
	FILE *p = popen(SKYD_BINARY " --list-keys", "re");

	while (p && fgets(line, sizeof(line), p) && f->n_keys < FUZZ_KEYS_MAX) {
		char *field[6] = { 0 }, *save = NULL;
		int n = 0;
		for (char *t = strtok_r(line, "\t\n", &save); t && n < 6; t = strtok_r(NULL, "\t\n", &save))
			field[n++] = t;
		if (n < 4)
			continue;
		int skip = 0;
		for (size_t i = 0; i < sizeof(skipped_keys) / sizeof(skipped_keys[0]); i++)
			skip |= !strcmp(field[0], skipped_keys[i]);
		if (skip)
			continue;
		struct key *k = &f->keys[f->n_keys++];
		memset(k, 0, sizeof(*k));
		snprintf(k->name, sizeof(k->name), "%s", field[0]);
		k->is_count = !strcmp(field[1], "texels") || !strcmp(field[1], "steps") ||
			      !strcmp(field[1], "slices") || !strcmp(field[1], "directions");
		k->is_vector = strchr(field[3], ',') != NULL;
		key_parse_range(k, field[2]);
		if (k->is_count && k->kind == R_INTERVAL && k->hi > FUZZ_COUNT_MAX)
			k->hi = FUZZ_COUNT_MAX;
	}
	if (p)
		pclose(p);
	return f->n_keys > 10 ? 0 : -1;
}

/* ---- values and requests ---- */

struct text {
	char s[FUZZ_REQ_MAX];
	size_t n;
};

static void put(struct text *t, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void put(struct text *t, const char *fmt, ...)
{
	va_list ap;

	if (t->n >= sizeof(t->s) - 1)
		return;
	va_start(ap, fmt);
	int k = vsnprintf(t->s + t->n, sizeof(t->s) - t->n, fmt, ap);
	va_end(ap);
	t->n += k < 0 ? 0 : (size_t)k;
	if (t->n > sizeof(t->s) - 1)
		t->n = sizeof(t->s) - 1;
}

/* A number of an interval: mostly inside, sometimes an end, rarely out. */
static double draw_number(struct fuzz *f, const struct key *k)
{
	struct rng *r = &f->rng;
	double lo = k->lo, hi = k->hi;

	switch (k->kind) {
	case R_ATLEAST:
		hi = lo + pow(10.0, rng_unit(r) * 6.0 - 3.0);
		break;
	case R_ATMOST:
		lo = hi - pow(10.0, rng_unit(r) * 6.0 - 3.0);
		break;
	case R_FINITE:
		lo = -pow(10.0, rng_unit(r) * 4.0 - 2.0);
		hi = -lo;
		break;
	default:
		break;
	}
	unsigned pick = rng_below(r, 20);
	double v = pick == 0 ? lo : pick == 1 ? hi : lo + (hi - lo) * rng_unit(r);
	if (pick == 2)	/* outside: refused, the state untouched */
		v = rng_chance(r, 0.5) ? lo - fabs(hi - lo) * 0.1 - 1 : hi + fabs(hi - lo) * 0.1 + 1;
	return k->is_count ? floor(v) : v;
}

static void put_value(struct fuzz *f, struct text *t, const struct key *k)
{
	struct rng *r = &f->rng;

	if (k->has_auto && rng_chance(r, 0.3)) {
		put(t, "auto");
		return;
	}
	switch (k->kind) {
	case R_NAMES:
		put(t, "%s", rng_chance(r, 0.05) ? "bogus" : k->names[rng_below(r, (unsigned)k->n_names)]);
		return;
	case R_TIME:
		if (rng_chance(r, 0.3))
			put(t, "now");
		else
			put(t, "%04u-%02u-%02uT%02u:%02u:%02u%s", 1900 + rng_below(r, 250),
			    1 + rng_below(r, 12), 1 + rng_below(r, 28), rng_below(r, 24),
			    rng_below(r, 60), rng_below(r, 60), rng_chance(r, 0.5) ? "Z" : "+02:00");
		return;
	case R_METAR:
		put(t, "\"%s\"", metars[rng_below(r, sizeof(metars) / sizeof(metars[0]))]);
		return;
	default:
		break;
	}
	int n = k->is_vector && rng_chance(r, 0.5) ? 3 : 1;
	for (int i = 0; i < n; i++)
		put(t, "%s%.9g", i ? "," : "", draw_number(f, k));
}

static void put_pairs(struct fuzz *f, struct text *t, int max)
{
	int n = 1 + (int)rng_below(&f->rng, (unsigned)max);

	for (int i = 0; i < n; i++) {
		const struct key *k = &f->keys[rng_below(&f->rng, (unsigned)f->n_keys)];
		put(t, " %s=", k->name);
		put_value(f, t, k);
	}
}

static const char *const tables[] = { "transmittance", "multiscatter", "skyview", "aerial", "all" };

static void gen_get(struct fuzz *f, struct text *t)
{
	struct rng *r = &f->rng;

	switch (rng_below(r, 7)) {
	case 0: put(t, "get"); break;
	case 1: put(t, "get sun"); break;
	case 2: put(t, "get moon"); break;
	case 3:
		put(t, "get times");
		if (rng_chance(r, 0.5))
			put(t, " date=%04u-%02u-%02u", 1800 + rng_below(r, 400), 1 + rng_below(r, 12),
			    1 + rng_below(r, 31));
		if (rng_chance(r, 0.5))
			put(t, " utc_offset_min=%d", (int)rng_below(r, 1801) - 900);
		break;
	case 4: put(t, "get weather"); break;
	case 5: put(t, "get sensor"); break;
	default:
		put(t, "get");
		for (unsigned i = 1 + rng_below(r, 4); i; i--)
			put(t, " %s", f->keys[rng_below(r, (unsigned)f->n_keys)].name);
	}
}

static void gen_subscribe(struct fuzz *f, struct text *t)
{
	struct rng *r = &f->rng;
	unsigned what = 1 + rng_below(r, 3);

	put(t, "subscribe");
	if (what & 1) {
		put(t, " tables=");
		for (unsigned i = 0, n = 1 + rng_below(r, 3); i < n; i++)
			put(t, "%s%s", i ? "," : "", tables[rng_below(r, 5)]);
	}
	if (what & 2)
		put(t, " events=%u", rng_below(r, 2));
}

static void gen_view(struct fuzz *f, struct text *t)
{
	static const char *const keys[] = { "altitude_km", "east_km", "north_km", "yaw_deg",
					    "pitch_deg", "roll_deg", "vfov_deg", "aspect" };
	static const double lo[] = { 0, -10000, -10000, -360, -90, -180, 1, 0.1 };
	static const double hi[] = { 30, 10000, 10000, 720, 90, 180, 170, 10 };
	struct rng *r = &f->rng;
	unsigned which = rng_below(r, 6);

	if (which == 5) {
		put(t, "view list");
		return;
	}
	put(t, "view %s name=v%u", which == 4 ? "del" : "add", rng_below(r, 5));
	if (which == 4)
		return;
	for (unsigned i = rng_below(r, 4); i; i--) {
		unsigned k = rng_below(r, 8);
		put(t, " %s=%.6g", keys[k], lo[k] + (hi[k] - lo[k]) * rng_unit(r));
	}
	if (rng_chance(r, 0.5))
		put(t, " form=%s", rng_chance(r, 0.5) ? "panorama" : "volume");
}

static void gen_sample(struct fuzz *f, struct text *t)
{
	struct rng *r = &f->rng;

	switch (rng_below(r, 3)) {
	case 0:
		put(t, "sample sky el_deg=%.4g az_deg=%.4g", -90 + 180 * rng_unit(r), 360 * rng_unit(r));
		break;
	case 1: put(t, "sample sun"); break;
	default: put(t, "sample ambient"); break;
	}
}

/* One request of verb (a batch: its lines, mostly with its end). */
static void gen_verb(struct fuzz *f, struct text *t, const char *verb)
{
	struct rng *r = &f->rng;

	if (!strcmp(verb, "set")) {
		put(t, "set");
		put_pairs(f, t, 4);
	} else if (!strcmp(verb, "get")) {
		gen_get(f, t);
	} else if (!strcmp(verb, "batch")) {
		put(t, "batch\n");
		for (unsigned i = rng_below(r, 5); i; i--) {
			put(t, "set");
			put_pairs(f, t, 3);
			put(t, "\n");
		}
		if (rng_chance(r, 0.85))
			put(t, "end");
		else
			t->n--;		/* left open: the connection's close ends it */
	} else if (!strcmp(verb, "subscribe")) {
		gen_subscribe(f, t);
	} else if (!strcmp(verb, "view")) {
		gen_view(f, t);
	} else if (!strcmp(verb, "sample")) {
		gen_sample(f, t);
	} else if (!strcmp(verb, "sensor")) {
		put(t, rng_chance(r, 0.5) ? "sensor list" : "sensor events=%u", rng_below(r, 2));
	} else if (!strcmp(verb, "help")) {
		put(t, "help");
		if (rng_chance(r, 0.7))
			put(t, " %s", f->verbs[rng_below(r, (unsigned)f->n_verbs)]);
	} else {
		/* commands, status, ping, close, unsubscribe, end, and any verb
		 * added since: bare, or with a key=value it may not take. */
		put(t, "%s", verb);
		if (rng_chance(r, 0.1))
			put_pairs(f, t, 2);
	}
	put(t, "\n");
}

/* Byte-level damage to a request: flips, cuts, insertions, a line over
 * SKY_PROTO_LINE_MAX, a NUL, an unknown verb. */
static void mutate(struct fuzz *f, struct text *t)
{
	struct rng *r = &f->rng;

	f->stats[S_MUTATED]++;
	for (unsigned i = 1 + rng_below(r, 3); i && t->n; i--) {
		size_t at = rng_below(r, (unsigned)t->n);
		switch (rng_below(r, 6)) {
		case 0: t->s[at] = (char)rng_below(r, 256); break;
		case 1: t->s[at] ^= (char)(1u << rng_below(r, 8)); break;
		case 2: t->n = at + 1; break;
		case 3:
			if (t->n + 1 < sizeof(t->s)) {
				memmove(t->s + at + 1, t->s + at, t->n - at);
				t->s[at] = "=\" ,\n\t\\\0"[rng_below(r, 8)];
				t->n++;
			}
			break;
		case 4:
			while (t->n < SKY_PROTO_LINE_MAX + 100 && t->n < sizeof(t->s) - 1)
				t->s[t->n++] = 'x';
			t->s[t->n++] = '\n';
			break;
		default:
			memcpy(t->s, "frobnicate ", at < 11 ? at : 11);
		}
	}
}

static void gen_request(struct fuzz *f, struct text *t)
{
	t->n = 0;
	gen_verb(f, t, f->verbs[rng_below(&f->rng, (unsigned)f->n_verbs)]);
	if (rng_chance(&f->rng, 0.1))
		mutate(f, t);
}

/* ---- connections ---- */

/* Reads what one connection has, waiting at most wait_ms for the first
 * bytes; an fd that comes along (a region) is mapped and read as a client
 * would, then closed. Counts the replies' last lines (OK, ACK) it sees.
 * Returns the bytes read, 0 at EOF or on an error, -1 when nothing came. */
static ssize_t drain(struct fuzz *f, struct fconn *c, int wait_ms, size_t max, int *ret_done)
{
	char buf[8192];
	union {
		char b[CMSG_SPACE(sizeof(int) * 8)];
		struct cmsghdr a;
	} u;
	struct pollfd p = { c->fd, POLLIN, 0 };

	if (poll(&p, 1, wait_ms) <= 0)
		return -1;
	struct iovec iov = { buf, max < sizeof(buf) ? max : sizeof(buf) };
	struct msghdr mh = { .msg_iov = &iov, .msg_iovlen = 1, .msg_control = u.b,
			     .msg_controllen = sizeof(u.b) };
	ssize_t n = recvmsg(c->fd, &mh, MSG_DONTWAIT | MSG_CMSG_CLOEXEC);
	for (struct cmsghdr *cm = CMSG_FIRSTHDR(&mh); n >= 0 && cm; cm = CMSG_NXTHDR(&mh, cm)) {
		if (cm->cmsg_level != SOL_SOCKET || cm->cmsg_type != SCM_RIGHTS)
			continue;
		for (size_t i = 0; i < (cm->cmsg_len - CMSG_LEN(0)) / sizeof(int); i++) {
			int fd;
			struct stat st;
			memcpy(&fd, CMSG_DATA(cm) + i * sizeof(int), sizeof(int));
			f->stats[S_FDS]++;
			if (rng_chance(&f->rng, 0.5) && fstat(fd, &st) == 0 &&
			    st.st_size >= (off_t)sizeof(struct sky_shm_header)) {
				const struct sky_shm_header *h =
					mmap(NULL, (size_t)st.st_size, PROT_READ, MAP_SHARED, fd, 0);
				if (h != MAP_FAILED) {
					seen_generation = __atomic_load_n(&h->generation, __ATOMIC_ACQUIRE);
					munmap((void *)h, (size_t)st.st_size);
				}
			}
			close(fd);
		}
	}
	if (n <= 0)
		return n < 0 && (errno == EAGAIN || errno == EINTR) ? -1 : 0;
	for (ssize_t i = 0; ret_done && i < n; i++) {
		if (buf[i] != '\n')
			continue;
		const char *line = buf + i;	/* the line before this newline, if it is here */
		while (line > buf && line[-1] != '\n')
			line--;
		if ((buf + i - line == 2 && !strncmp(line, "OK", 2)) || !strncmp(line, "ACK [", 5))
			(*ret_done)++;
	}
	return n;
}

static void drain_all(struct fuzz *f)
{
	for (int i = 0; i < FUZZ_CONNS; i++) {
		struct fconn *c = &f->conns[i];
		if (c->fd >= 0 && !c->stalled && drain(f, c, 0, SIZE_MAX, NULL) == 0) {
			close(c->fd);	/* skyd hung up: refused, or dropped */
			c->fd = -1;
		}
	}
}

static void conn_shut(struct fuzz *f, struct fconn *c, int reset)
{
	if (reset) {
		/* A reset instead of a FIN: skyd's next write fails at once. */
		struct linger l = { 1, 0 };
		setsockopt(c->fd, SOL_SOCKET, SO_LINGER, &l, sizeof(l));
		f->stats[S_RESETS]++;
	}
	close(c->fd);
	c->fd = -1;
	f->stats[S_CLOSES]++;
}

static int conn_new(struct fuzz *f, struct fconn *c)
{
	c->fd = conn_raw(f->d.sock);
	c->stalled = 0;
	if (c->fd < 0)
		return -1;
	fcntl(c->fd, F_SETFL, fcntl(c->fd, F_GETFL) | O_NONBLOCK);
	note(f, "open %d", (int)(c - f->conns));
	return 0;
}

/* Sends a request, sometimes in two writes that split its lines where
 * skyd's framing must join them. What the socket does not take is lost:
 * a cut request is one more input. */
static void send_request(struct fuzz *f, struct fconn *c, const struct text *t)
{
	char shown[64];
	size_t cut = rng_chance(&f->rng, 0.2) ? rng_below(&f->rng, (unsigned)t->n + 1) : t->n;

	snprintf(shown, sizeof(shown), "%.*s", (int)(t->n < 60 ? t->n : 60), t->s);
	for (char *p = shown; *p; p++)
		if ((unsigned char)*p < 32 || (unsigned char)*p > 126)
			*p = '.';
	note(f, "conn %d: %s%s", (int)(c - f->conns), shown, cut < t->n ? " (in two writes)" : "");
	f->stats[S_REQUESTS]++;
	if (send(c->fd, t->s, cut, MSG_NOSIGNAL | MSG_DONTWAIT) < 0)
		return;
	if (cut < t->n) {
		drain(f, c, 0, SIZE_MAX, NULL);
		send(c->fd, t->s + cut, t->n - cut, MSG_NOSIGNAL | MSG_DONTWAIT);
	}
}

/* Closes c with a request just sent: before its reply, during it (some
 * bytes read) or after it (its last line read, or two seconds). */
static void act_close(struct fuzz *f, struct fconn *c)
{
	static const char *const when[] = { "before", "during", "after", "idle" };
	struct text t;
	unsigned mode = rng_below(&f->rng, 4);
	int reset = rng_chance(&f->rng, 0.3), done = 0;

	if (mode < 3) {
		gen_request(f, &t);
		send_request(f, c, &t);
	}
	note(f, "close %d %s its reply%s", (int)(c - f->conns), when[mode], reset ? ", reset" : "");
	if (mode == 1)
		drain(f, c, 500, 1 + rng_below(&f->rng, 64), NULL);
	for (int i = 0; mode == 2 && !done && i < 20 && drain(f, c, 100, SIZE_MAX, &done) != 0; i++)
		;
	conn_shut(f, c, reset);
}

/* skyd stopped while lines arrive and their sender goes: running again it
 * finds both at once, and its first write to that peer fails inside the
 * last request it handles (test_daemon_client_vanish). */
static int act_vanish(struct fuzz *f, struct fconn *c)
{
	struct text t;
	int status, reset = rng_chance(&f->rng, 0.3);

	if (kill(f->d.pid, SIGSTOP) < 0 || waitpid(f->d.pid, &status, WUNTRACED) != f->d.pid ||
	    !WIFSTOPPED(status))
		return -1;
	note(f, "skyd stopped");
	if (rng_chance(&f->rng, 0.5)) {
		t.n = 0;
		put(&t, "subscribe events=1%s\n", rng_chance(&f->rng, 0.5) ? " tables=all" : "");
		send_request(f, c, &t);
	}
	for (unsigned i = 1 + rng_below(&f->rng, 3); i; i--) {
		gen_request(f, &t);
		send_request(f, c, &t);
	}
	note(f, "close %d, skyd continued%s", (int)(c - f->conns), reset ? ", reset" : "");
	conn_shut(f, c, reset);
	f->stats[S_VANISHES]++;
	kill(f->d.pid, SIGCONT);
	return waitpid(f->d.pid, &status, WCONTINUED) == f->d.pid && WIFCONTINUED(status) ? 0 : -1;
}

/* A subscriber that never reads again: skyd's bound on its output queue
 * drops it, perhaps while it publishes to everyone. */
static void act_stall(struct fuzz *f, struct fconn *c)
{
	struct text t = { .n = 0 };

	put(&t, "subscribe events=1%s\n", rng_chance(&f->rng, 0.5) ? " tables=all" : "");
	send_request(f, c, &t);
	note(f, "conn %d stalls", (int)(c - f->conns));
	c->stalled = 1;
}

/* ---- a round: one skyd, one seed ---- */

static int skyd_alive(struct fuzz *f, char *why, size_t size)
{
	int status;
	pid_t p = waitpid(f->d.pid, &status, WNOHANG);

	if (p == 0)
		return 1;
	if (p == f->d.pid) {
		f->d.pid = 0;
		if (WIFSIGNALED(status))
			snprintf(why, size, "skyd died of signal %d", WTERMSIG(status));
		else
			snprintf(why, size, "skyd exited %d", WEXITSTATUS(status));
	} else {
		snprintf(why, size, "waitpid: %s", strerror(errno));
	}
	return 0;
}

/* A process's or thread's state letter, CPU seconds and nice value from
 * its stat file; 0, or -1 when it is gone. */
static int proc_stat(const char *path, char *state, double *cpu_s, long *nice)
{
	char buf[1024];
	FILE *fp = fopen(path, "re");
	size_t n = fp ? fread(buf, 1, sizeof(buf) - 1, fp) : 0;
	unsigned long long ut, st;

	if (fp)
		fclose(fp);
	buf[n] = 0;
	char *p = strrchr(buf, ')');
	if (!p || sscanf(p + 2, "%c %*d %*d %*d %*d %*d %*u %*u %*u %*u %*u %llu %llu %*d %*d %*d %ld",
			 state, &ut, &st, nice) != 4)
		return -1;
	*cpu_s = (double)(ut + st) / (double)sysconf(_SC_CLK_TCK);
	return 0;
}

/* Why skyd did not answer: how much CPU it got while the ping waited,
 * its nice value, and each thread's state and where it sleeps; a skyd that
 * was runnable and got little CPU was starved by the machine's load, one
 * asleep with its loop thread blocked hangs. */
static void describe_stall(pid_t pid, double cpu0_s, char *why, size_t size)
{
	char path[128], state = '?';
	double cpu_s = 0;
	long nice = 0;
	size_t n = strlen(why);

	snprintf(path, sizeof(path), "/proc/%d/stat", (int)pid);
	if (proc_stat(path, &state, &cpu_s, &nice) < 0)
		return;
	n += (size_t)snprintf(why + n, size - n, "; skyd %c, nice %ld, %.2f s of CPU while it waited;"
			      " threads:", state, nice, cpu_s - cpu0_s);
	snprintf(path, sizeof(path), "/proc/%d/task", (int)pid);
	DIR *dir = opendir(path);
	for (struct dirent *e; dir && (e = readdir(dir)) && n + 64 < size;) {
		char wchan[64] = "", tstat[160];
		if (e->d_name[0] == '.')
			continue;
		snprintf(tstat, sizeof(tstat), "/proc/%d/task/%.16s/wchan", (int)pid, e->d_name);
		FILE *fp = fopen(tstat, "re");
		if (fp) {
			(void)!fgets(wchan, sizeof(wchan), fp);
			fclose(fp);
		}
		snprintf(tstat, sizeof(tstat), "/proc/%d/task/%.16s/stat", (int)pid, e->d_name);
		double t_cpu;
		long t_nice;
		if (proc_stat(tstat, &state, &t_cpu, &t_nice) == 0)
			n += (size_t)snprintf(why + n, size - n, " %.16s %c %s", e->d_name, state,
					      wchan[0] ? wchan : "-");
	}
	if (dir)
		closedir(dir);
}

static int probe_ping(struct fuzz *f, char *why, size_t size)
{
	char reply[256], path[64], state;
	double cpu0_s = 0;
	long nice;

	f->stats[S_PINGS]++;
	snprintf(path, sizeof(path), "/proc/%d/stat", (int)f->d.pid);
	(void)proc_stat(path, &state, &cpu0_s, &nice);
	if (conn_request(&f->probe, "ping", reply, sizeof(reply)) == 0)
		return 0;
	snprintf(why, size, "skyd did not answer ping within %d ms", HARNESS_TIMEOUT_MS);
	describe_stall(f->d.pid, cpu0_s, why, size);
	return -1;
}

static struct fconn *pick_open(struct fuzz *f, int stalled_too)
{
	unsigned start = rng_below(&f->rng, FUZZ_CONNS);

	for (unsigned i = 0; i < FUZZ_CONNS; i++) {
		struct fconn *c = &f->conns[(start + i) % FUZZ_CONNS];
		if (c->fd >= 0 && (stalled_too || !c->stalled))
			return c;
	}
	return NULL;
}

static struct fconn *pick_free(struct fuzz *f)
{
	for (int i = 0; i < FUZZ_CONNS; i++)
		if (f->conns[i].fd < 0)
			return &f->conns[i];
	return NULL;
}

/* One step: an action drawn from the seed. 0, or -1 with why. */
static int step(struct fuzz *f, char *why, size_t size)
{
	struct rng *r = &f->rng;
	struct fconn *c = pick_open(f, 0), *any = pick_open(f, 1), *free_c = pick_free(f);
	double a = rng_unit(r);
	struct text t;

	if (free_c && (!c || a < 0.08)) {
		conn_new(f, free_c);
	} else if (c && a < 0.60) {
		gen_request(f, &t);
		send_request(f, c, &t);
	} else if (any && a < 0.72) {
		act_close(f, any);
	} else if (c && a < 0.75) {
		if (act_vanish(f, c) < 0) {
			snprintf(why, size, "could not stop and continue skyd: %s", strerror(errno));
			return -1;
		}
	} else if (c && a < 0.77) {
		act_stall(f, c);
	} else {
		drain_all(f);
	}
	if (rng_chance(r, 0.5))
		drain_all(f);
	if ((f->step % 16 == 0 && !skyd_alive(f, why, size)) ||
	    (f->step % FUZZ_PING_EVERY == 0 && probe_ping(f, why, size) < 0))
		return -1;
	return 0;
}

/* The verbs of skyd's command table, from `commands` on the probe. */
static int load_verbs(struct fuzz *f)
{
	char reply[4096];

	f->n_verbs = 0;
	if (conn_request(&f->probe, "commands", reply, sizeof(reply)) != 0)
		return -1;
	for (const char *p = reply; (p = strstr(p, "command: ")) && f->n_verbs < FUZZ_VERBS_MAX;) {
		p += 9;
		size_t n = strcspn(p, "\n");
		snprintf(f->verbs[f->n_verbs++], sizeof(f->verbs[0]), "%.*s", (int)n, p);
	}
	return f->n_verbs > 5 ? 0 : -1;
}

/* A sanitizer's report for skyd's pid, where its options send reports
 * (log_path of ASAN_OPTIONS, UBSAN_OPTIONS, TSAN_OPTIONS): printed, 1. */
static int sanitizer_report(pid_t pid)
{
	static const char *const vars[] = { "ASAN_OPTIONS", "UBSAN_OPTIONS", "TSAN_OPTIONS" };
	int found = 0;

	for (size_t i = 0; i < sizeof(vars) / sizeof(vars[0]); i++) {
		const char *o = getenv(vars[i]), *lp = o ? strstr(o, "log_path=") : NULL;
		char path[512], cmd[600];
		struct stat st;
		if (!lp)
			continue;
		lp += 9;
		snprintf(path, sizeof(path), "%.*s.%d", (int)strcspn(lp, ":"), lp, (int)pid);
		if (stat(path, &st) != 0 || st.st_size == 0)
			continue;
		fprintf(stderr, "test_daemon_fuzz: %s:\n", path);
		snprintf(cmd, sizeof(cmd), "cat '%s' >&2", path);
		(void)!system(cmd);
		found = 1;
	}
	return found;
}

static void report_failure(struct fuzz *f, const char *why, const char *self)
{
	char cmd[300];

	fprintf(stderr, "test_daemon_fuzz: seed %llu, step %d: %s\n", (unsigned long long)f->seed,
		f->step, why);
	fprintf(stderr, "the last actions:\n");
	int first = f->n_trail > FUZZ_TRAIL ? f->n_trail - FUZZ_TRAIL : 0;
	for (int i = first; i < f->n_trail; i++)
		fprintf(stderr, "  %s\n", f->trail[i % FUZZ_TRAIL]);
	fprintf(stderr, "skyd's log, its end:\n");
	snprintf(cmd, sizeof(cmd), "tail -n 40 '%s' >&2", f->d.log);
	(void)!system(cmd);
	fprintf(stderr, "again: %s --seed %llu --rounds 1 --steps %d\n", self,
		(unsigned long long)f->seed, f->step + 1);
}

/* The bounds of this round's skyd, from its seed: small ones are reached
 * (refused connections, subscriptions and views), the defaults are not. */
static void round_args(struct fuzz *f, const char **argv, char bufs[3][16])
{
	static const char *const small[] = { HARNESS_SMALL };
	int n = 0;

	snprintf(bufs[0], 16, "%u", rng_chance(&f->rng, 0.3) ? 4 : 1024);
	snprintf(bufs[1], 16, "%u", rng_chance(&f->rng, 0.3) ? 2 : 64);
	snprintf(bufs[2], 16, "%u", rng_chance(&f->rng, 0.3) ? 2 : 64);
	argv[n++] = "--max-connections";
	argv[n++] = bufs[0];
	argv[n++] = "--max-subscriptions-per-uid";
	argv[n++] = bufs[1];
	argv[n++] = "--max-views-per-uid";
	argv[n++] = bufs[2];
	for (size_t i = 0; i < sizeof(small) / sizeof(small[0]); i++)
		argv[n++] = small[i];
	argv[n] = NULL;
}

/* The end of a round: every connection closed, the probe answered, skyd
 * stopped by SIGTERM and exited 0 (LeakSanitizer's exit is not), no report. */
static int round_end(struct fuzz *f, char *why, size_t size)
{
	for (int i = 0; i < FUZZ_CONNS; i++)
		if (f->conns[i].fd >= 0)
			conn_shut(f, &f->conns[i], 0);
	if (!skyd_alive(f, why, size) || probe_ping(f, why, size) < 0)
		return -1;
	conn_close(&f->probe);
	pid_t pid = f->d.pid;
	int status = daemon_stop(&f->d, SIGTERM);
	if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
		snprintf(why, size, "skyd's exit on SIGTERM: %s %d",
			 WIFSIGNALED(status) ? "signal" : "status",
			 WIFSIGNALED(status) ? WTERMSIG(status) : WEXITSTATUS(status));
		sanitizer_report(pid);
		return -1;
	}
	if (sanitizer_report(pid)) {
		snprintf(why, size, "a sanitizer's report");
		return -1;
	}
	return 0;
}

static int round_run(struct fuzz *f, uint64_t seed, int steps, double deadline_s,
		     const char *self)
{
	const char *argv[64];
	char bufs[3][16], why[1024] = "";
	int r = -1;

	f->seed = seed;
	f->rng.s = seed;
	f->step = 0;
	f->n_trail = 0;
	for (int i = 0; i < FUZZ_CONNS; i++)
		f->conns[i].fd = -1;
	round_args(f, argv, bufs);
	if (daemon_start(&f->d, argv) < 0) {
		snprintf(why, sizeof(why), "skyd did not start");
		goto out;
	}
	if (conn_open(&f->probe, f->d.sock) < 0 || load_verbs(f) < 0) {
		snprintf(why, sizeof(why), "no probe connection, or no verbs from commands");
		goto out;
	}
	for (; f->step < steps && fuzz_now_s() < deadline_s; f->step++)
		if (step(f, why, sizeof(why)) < 0)
			goto out;
	r = round_end(f, why, sizeof(why));
out:
	if (r < 0)
		report_failure(f, why, self);
	for (int i = 0; i < FUZZ_CONNS; i++)
		if (f->conns[i].fd >= 0)
			close(f->conns[i].fd);
	conn_close(&f->probe);
	if (f->d.pid > 0)
		kill(f->d.pid, SIGCONT);
	daemon_cleanup(&f->d);
	return r;
}

int main(int argc, char **argv)
{
	static struct fuzz f;
	unsigned long long seed = 1;
	double seconds = 20;
	long rounds = -1, steps = 3000;
	int keep_going = 0;

	for (int i = 1; i < argc; i++) {
		if (!strcmp(argv[i], "--keep-going"))
			keep_going = 1;
		else if (i + 1 >= argc)
			break;
		else if (!strcmp(argv[i], "--seed"))
			seed = strtoull(argv[++i], NULL, 0);
		else if (!strcmp(argv[i], "--seconds"))
			seconds = atof(argv[++i]);
		else if (!strcmp(argv[i], "--rounds"))
			rounds = atol(argv[++i]);
		else if (!strcmp(argv[i], "--steps"))
			steps = atol(argv[++i]);
	}
	harness_need_device();
	if (load_keys(&f) < 0) {
		FAIL("no keys from %s --list-keys", SKYD_BINARY);
		return test_report("test_daemon_fuzz");
	}
	double start = fuzz_now_s(), deadline = start + seconds;
	long done = 0, total_steps = 0;
	for (; (rounds < 0 || done < rounds) && (done == 0 || fuzz_now_s() < deadline); done++) {
		if (round_run(&f, seed + (uint64_t)done, (int)steps, rounds < 0 ? deadline : 1e300,
			      argv[0]) < 0)
			test_failures++;
		total_steps += f.step;
		if (test_failures && !keep_going) {
			done++;
			break;
		}
	}
	printf("test_daemon_fuzz: %ld rounds (%d failed) from seed %llu, %ld steps in %.0f s, %d keys, %d verbs: "
	       "%lu requests (%lu mutated), %lu closes (%lu resets), %lu vanishes, %lu fds, "
	       "%lu pings\n", done, (int)test_failures, seed, total_steps, fuzz_now_s() - start,
	       f.n_keys, f.n_verbs,
	       f.stats[S_REQUESTS], f.stats[S_MUTATED], f.stats[S_CLOSES], f.stats[S_RESETS],
	       f.stats[S_VANISHES], f.stats[S_FDS], f.stats[S_PINGS]);
	return test_report("test_daemon_fuzz");
}
