/* sky.c - libsky's connection to skyd: the control socket, requests and
 * replies, events, the read-only mapping of the published tables, seqlock
 * views and the futex wait. The manual is sky.h. */
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <linux/futex.h>
#include <poll.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>

#include "sky.h"
#include "skysample.h"

#define SKY_MAX_PENDING 64		/* requests waiting for their reply */
#define SKY_MAX_REPLY_LINES 65536	/* a reply longer than this is garbage */
#define SKY_IN_MAX (1u << 20)		/* bytes of one incoming line, bounded */
#define SKY_OUT_MAX (SKY_MAX_PENDING * SKY_PROTO_LINE_MAX)
#define SKY_MAX_FDS 8
#define SKY_VIEW_TRIES 64
#define SKY_SNAPSHOT_TRIES 16
#define SKY_DEFAULT_TIMEOUT_MS 5000

static const char *const table_names[SKY_SHM_MAX_TABLES] = {
	"transmittance", "multiscatter", "skyview", "aerial",
};

struct sky_reply {
	int ack;
	int fd;				/* descriptor that came with it, -1 if none */
	char *message;
	size_t n, cap;
	char **keys, **values;
};

struct sky_pending {
	uint64_t userdata;
	bool sync;			/* sky_request() is waiting for it */
	bool subscribe;			/* its reply carries the memfd */
};

struct sky_queued {
	struct sky_event ev;
	sky_reply *owned;
};

struct sky_client {
	char path[sizeof(((struct sockaddr_un *)0)->sun_path)];
	int fd;
	bool hung_up;
	bool greeted;
	char proto_version[32];
	int timeout_ms;
	uint64_t bytes_sent;		/* since connect, to know what reached the peer */

	char *in;
	size_t in_len, in_cap;
	char *out;
	size_t out_len, out_off;

	struct sky_pending pend[SKY_MAX_PENDING];
	unsigned pend_head, pend_count;
	sky_reply *cur;			/* reply being read */
	int fds[SKY_MAX_FDS];
	unsigned n_fds;

	struct sky_queued *evq;
	size_t ev_head, ev_count, ev_cap;
	sky_reply *handed_out;		/* reply of the last dispatched event */
	sky_reply *sync_reply;		/* completed reply of sky_request() */
	bool sync_done;

	bool in_batch;			/* lines after "batch" get no reply until "end" */
	bool unanswered;		/* the last queued line expects no reply */

	uint32_t sub_tables;
	unsigned sub_flags;
	bool subscribed;
	int map_error;			/* result of mapping the last subscribe's memfd */
	const struct sky_shm_header *map;
	size_t map_bytes;
	const struct sky_shm_header *old_map;	/* sky_wait: the superseded region */
};

/* ---- small helpers ------------------------------------------------------ */

unsigned sky_version(void)
{
	return SKY_VERSION;
}

const char *sky_strerror(int err)
{
	if (err > 0) {
		switch (err) {
		case SKY_ACK_SYNTAX: return "daemon refused: syntax";
		case SKY_ACK_ARG: return "daemon refused: bad argument";
		case SKY_ACK_PERMISSION: return "daemon refused: permission";
		case SKY_ACK_UNKNOWN: return "daemon refused: unknown verb";
		case SKY_ACK_NO_EXIST: return "daemon refused: no such key or table";
		case SKY_ACK_RANGE: return "daemon refused: out of range";
		case SKY_ACK_LIMIT: return "daemon refused: limit reached";
		case SKY_ACK_TOO_LONG: return "daemon refused: line too long";
		case SKY_ACK_STATE: return "daemon refused: not allowed now";
		case SKY_ACK_ENGINE: return "daemon failed: engine error";
		default: return "daemon refused";
		}
	}
	switch (-err) {
	case 0: return "success";
	case EINVAL: return "invalid argument";
	case ENOENT: return "no such socket (is skyd running?)";
	case ECONNREFUSED: return "connection refused (is skyd running?)";
	case ECONNRESET: return "skyd closed the connection";
	case EPIPE: return "skyd closed the connection";
	case ENOTCONN: return "not connected or not subscribed";
	case ETIMEDOUT: return "timed out";
	case EPROTO: return "protocol error (garbled reply or shared memory)";
	case EPROTONOSUPPORT: return "protocol or layout version not supported";
	case EAGAIN: return "try again (writer busy or queue full)";
	case ENODATA: return "table not valid in this slot";
	case ENOBUFS: return "buffer too small";
	case ENOMEM: return "out of memory";
	case EACCES: return "permission denied";
	case ENAMETOOLONG: return "path too long";
	case EINTR: return "interrupted";
	default: return "system error";
	}
}

int sky_default_path(char *buf, size_t size)
{
	if (!buf || !size)
		return -EINVAL;
	const char *xdg = getenv("XDG_RUNTIME_DIR");
	char tmp[PATH_MAX];
	const char *p = "/run/skyd/control";
	if (xdg && xdg[0] == '/') {
		int n = snprintf(tmp, sizeof(tmp), "%s/skyd/control", xdg);
		if (n > 0 && (size_t)n < sizeof(tmp) && access(tmp, F_OK) == 0)
			p = tmp;
	}
	size_t n = strlen(p);
	if (n >= size || n >= sizeof(((struct sockaddr_un *)0)->sun_path))
		return -ENAMETOOLONG;
	memcpy(buf, p, n + 1);
	return (int)n;
}

static int64_t now_ms(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (int64_t)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
}

/* Milliseconds left before deadline (-1: none) for poll(). */
static int left_ms(int64_t deadline)
{
	if (deadline < 0)
		return -1;
	int64_t d = deadline - now_ms();
	return d < 0 ? 0 : d > INT_MAX ? INT_MAX : (int)d;
}

static char *dup_n(const char *s, size_t n)
{
	char *d = malloc(n + 1);
	if (d) {
		memcpy(d, s, n);
		d[n] = 0;
	}
	return d;
}

/* ---- replies ------------------------------------------------------------ */

static sky_reply *reply_new(void)
{
	sky_reply *r = calloc(1, sizeof(*r));
	if (r)
		r->fd = -1;
	return r;
}

void sky_reply_free(sky_reply *r)
{
	if (!r)
		return;
	for (size_t i = 0; i < r->n; i++) {
		free(r->keys[i]);
		free(r->values[i]);
	}
	free(r->keys);
	free(r->values);
	free(r->message);
	if (r->fd >= 0)
		close(r->fd);
	free(r);
}

static int reply_add(sky_reply *r, const char *line, size_t len)
{
	if (r->n >= SKY_MAX_REPLY_LINES)
		return -EPROTO;
	if (r->n == r->cap) {
		size_t cap = r->cap ? r->cap * 2 : 16;
		char **k = realloc(r->keys, cap * sizeof(*k));
		if (!k)
			return -ENOMEM;
		r->keys = k;
		char **v = realloc(r->values, cap * sizeof(*v));
		if (!v)
			return -ENOMEM;
		r->values = v;
		r->cap = cap;
	}
	const char *colon = memchr(line, ':', len);
	size_t kl = colon ? (size_t)(colon - line) : len;
	const char *val = colon ? colon + 1 : line + len;
	while (val < line + len && *val == ' ')
		val++;
	char *k = dup_n(line, kl), *v = dup_n(val, (size_t)(line + len - val));
	if (!k || !v) {
		free(k);
		free(v);
		return -ENOMEM;
	}
	r->keys[r->n] = k;
	r->values[r->n] = v;
	r->n++;
	return 0;
}

int sky_reply_ack(const sky_reply *r)
{
	return r ? r->ack : -EINVAL;
}

const char *sky_reply_message(const sky_reply *r)
{
	return r && r->message ? r->message : "";
}

size_t sky_reply_count(const sky_reply *r)
{
	return r ? r->n : 0;
}

const char *sky_reply_key(const sky_reply *r, size_t i)
{
	return r && i < r->n ? r->keys[i] : NULL;
}

const char *sky_reply_value(const sky_reply *r, size_t i)
{
	return r && i < r->n ? r->values[i] : NULL;
}

const char *sky_reply_get(const sky_reply *r, const char *key)
{
	if (!r || !key)
		return NULL;
	for (size_t i = 0; i < r->n; i++)
		if (strcmp(r->keys[i], key) == 0)
			return r->values[i];
	return NULL;
}

/* ---- events ------------------------------------------------------------- */

static int event_push(sky_client *c, const struct sky_event *ev, sky_reply *owned)
{
	if (c->ev_count == c->ev_cap) {
		size_t cap = c->ev_cap ? c->ev_cap * 2 : 16;
		struct sky_queued *q = malloc(cap * sizeof(*q));
		if (!q)
			return -ENOMEM;
		for (size_t i = 0; i < c->ev_count; i++)
			q[i] = c->evq[(c->ev_head + i) % c->ev_cap];
		free(c->evq);
		c->evq = q;
		c->ev_head = 0;
		c->ev_cap = cap;
	}
	struct sky_queued *slot = &c->evq[(c->ev_head + c->ev_count) % c->ev_cap];
	slot->ev = *ev;
	slot->owned = owned;
	c->ev_count++;
	return 0;
}

static void events_clear(sky_client *c)
{
	for (size_t i = 0; i < c->ev_count; i++)
		sky_reply_free(c->evq[(c->ev_head + i) % c->ev_cap].owned);
	c->ev_head = c->ev_count = 0;
	sky_reply_free(c->handed_out);
	c->handed_out = NULL;
}

/* ---- the mapping ---------------------------------------------------------- */

static void unmap(sky_client *c)
{
	if (c->map)
		munmap((void *)c->map, c->map_bytes);
	c->map = NULL;
	c->map_bytes = 0;
}

/* Maps memfd read-only after checking that it cannot shrink under us (a
 * shrink would turn our reads into SIGBUS) and that its header is sane.
 * Takes ownership of fd. */
static int map_memfd(sky_client *c, int fd)
{
	struct stat st;
	int r;
	if (fstat(fd, &st) < 0) {
		r = -errno;
		goto out;
	}
	int seals = fcntl(fd, F_GET_SEALS);
	if (seals < 0 || !(seals & F_SEAL_SHRINK) || st.st_size < (off_t)sizeof(struct sky_shm_header)) {
		r = -EPROTO;
		goto out;
	}
	void *m = mmap(NULL, (size_t)st.st_size, PROT_READ, MAP_SHARED, fd, 0);
	if (m == MAP_FAILED) {
		r = -errno;
		goto out;
	}
	r = skysample_check_layout(m, (uint64_t)st.st_size);
	if (r < 0) {
		munmap(m, (size_t)st.st_size);
		goto out;
	}
	unmap(c);
	c->map = m;
	c->map_bytes = (size_t)st.st_size;
	r = 0;
out:
	close(fd);
	return r;
}

/* ---- the socket ----------------------------------------------------------- */

static void close_fds(sky_client *c)
{
	for (unsigned i = 0; i < c->n_fds; i++)
		close(c->fds[i]);
	c->n_fds = 0;
}

/* Forgets the connection: socket, buffers, pending requests. Keeps the
 * mapping (still readable) and the queued events. */
static void drop_connection(sky_client *c)
{
	if (c->fd >= 0)
		close(c->fd);
	c->fd = -1;
	c->in_len = 0;
	c->out_len = c->out_off = 0;
	c->pend_count = c->pend_head = 0;
	c->in_batch = false;
	sky_reply_free(c->cur);
	c->cur = NULL;
	close_fds(c);
	c->greeted = false;
}

static void hang_up(sky_client *c)
{
	if (c->fd < 0 && c->hung_up)
		return;
	drop_connection(c);
	c->hung_up = true;
	struct sky_event ev = { .type = SKY_EVENT_HANGUP };
	(void)event_push(c, &ev, NULL);
}

/* The unsolicited lines of the protocol: "changed: ", "failed: " and
 * "layout: ". They come only between whole replies. */
static bool is_event_line(const char *line, size_t len)
{
	static const char *const pfx[] = { "changed: ", "failed: ", "layout: " };
	for (size_t i = 0; i < sizeof(pfx) / sizeof(pfx[0]); i++) {
		size_t n = strlen(pfx[i]);
		if (len >= n && memcmp(line, pfx[i], n) == 0)
			return true;
	}
	return false;
}

static uint32_t parse_tables(char *list)
{
	uint32_t mask = 0;
	char *save = NULL;
	for (char *t = strtok_r(list, ",", &save); t; t = strtok_r(NULL, ",", &save)) {
		for (unsigned i = 0; i < SKY_SHM_MAX_TABLES; i++)
			if (strcmp(t, table_names[i]) == 0)
				mask |= SKY_TABLE_BIT(i);
		if (strcmp(t, "all") == 0)
			mask = SKY_TABLES_ALL;
	}
	return mask;
}

/* "changed: generation=N tables=a,b", "failed: generation=N message=text",
 * "layout: generation=N bytes=B" (with the new memfd) -> events. Unknown
 * words are ignored: a later protocol may add some. */
static int handle_event_line(sky_client *c, const char *line, size_t len)
{
	struct sky_event ev = { .type = SKY_EVENT_CHANGED };
	sky_reply *owned = NULL;
	char buf[512];
	size_t n = len < sizeof(buf) - 1 ? len : sizeof(buf) - 1;
	memcpy(buf, line, n);
	buf[n] = 0;
	char *colon = strchr(buf, ':');
	*colon = 0;
	if (strcmp(buf, "failed") == 0)
		ev.type = SKY_EVENT_FAILED;
	else if (strcmp(buf, "layout") == 0)
		ev.type = SKY_EVENT_LAYOUT;
	char *save = NULL;
	for (char *w = strtok_r(colon + 1, " ", &save); w; w = strtok_r(NULL, " ", &save)) {
		if (strncmp(w, "generation=", 11) == 0) {
			ev.generation = (uint32_t)strtoull(w + 11, NULL, 10);
		} else if (strncmp(w, "tables=", 7) == 0) {
			ev.tables = parse_tables(w + 7);
		} else if (strncmp(w, "message=", 8) == 0 && !owned) {
			if (!(owned = reply_new()) || !(owned->message = strdup(w + 8))) {
				sky_reply_free(owned);
				return -ENOMEM;
			}
			ev.message = owned->message;
		}
	}
	if (ev.type == SKY_EVENT_LAYOUT) {
		/* The new region came with the line; without it the line is garbage. */
		if (!c->n_fds)
			return -EPROTO;
		int fd = c->fds[0];
		memmove(c->fds, c->fds + 1, --c->n_fds * sizeof(int));
		int r = map_memfd(c, fd);
		if (r < 0)
			return r;
	}
	int r = event_push(c, &ev, owned);
	if (r < 0)
		sky_reply_free(owned);
	return r;
}

static int complete_reply(sky_client *c)
{
	sky_reply *r = c->cur;
	c->cur = NULL;
	if (!c->pend_count) {
		sky_reply_free(r);
		return -EPROTO;
	}
	struct sky_pending p = c->pend[c->pend_head];
	c->pend_head = (c->pend_head + 1) % SKY_MAX_PENDING;
	c->pend_count--;
	if (p.subscribe && r->ack == 0) {
		if (c->n_fds) {
			int fd = c->fds[0];
			memmove(c->fds, c->fds + 1, --c->n_fds * sizeof(int));
			c->map_error = map_memfd(c, fd);
		} else {
			c->map_error = -EPROTO;
		}
	}
	if (p.sync) {
		c->sync_reply = r;
		c->sync_done = true;
		return 0;
	}
	struct sky_event ev = { .type = SKY_EVENT_REPLY, .userdata = p.userdata, .ack = r->ack,
				.reply = r };
	int e = event_push(c, &ev, r);
	if (e < 0)
		sky_reply_free(r);
	return e;
}

static int handle_line(sky_client *c, char *line, size_t len)
{
	if (len && line[len - 1] == '\r')
		line[--len] = 0;
	if (!c->greeted) {
		/* "OK skyd <version>" */
		if (len < 8 || memcmp(line, "OK skyd ", 8) != 0 || len - 8 >= sizeof(c->proto_version))
			return -EPROTO;
		memcpy(c->proto_version, line + 8, len - 8);
		c->proto_version[len - 8] = 0;
		size_t a = strcspn(c->proto_version, "."), b = strcspn(SKY_PROTO_VERSION, ".");
		if (a != b || memcmp(c->proto_version, SKY_PROTO_VERSION, a) != 0)
			return -EPROTONOSUPPORT;
		c->greeted = true;
		return 0;
	}
	if ((!c->cur || c->cur->n == 0) && is_event_line(line, len))
		return handle_event_line(c, line, len);
	if (!c->cur && !(c->cur = reply_new()))
		return -ENOMEM;
	if (len == 2 && memcmp(line, "OK", 2) == 0)
		return complete_reply(c);
	if (len >= 5 && memcmp(line, "ACK [", 5) == 0) {
		char *end;
		long code = strtol(line + 5, &end, 10);
		if (end == line + 5 || *end != ']' || code <= 0 || code > 9999)
			return -EPROTO;
		end++;
		while (*end == ' ')
			end++;
		c->cur->ack = (int)code;
		if (!(c->cur->message = strdup(end)))
			return -ENOMEM;
		return complete_reply(c);
	}
	return reply_add(c->cur, line, len);
}

static int handle_input(sky_client *c)
{
	size_t start = 0;
	int r = 0;
	for (;;) {
		char *nl = memchr(c->in + start, '\n', c->in_len - start);
		if (!nl)
			break;
		*nl = 0;
		r = handle_line(c, c->in + start, (size_t)(nl - (c->in + start)));
		start = (size_t)(nl - c->in) + 1;
		if (r < 0)
			break;
	}
	memmove(c->in, c->in + start, c->in_len - start);
	c->in_len -= start;
	if (r == 0 && c->in_len >= SKY_IN_MAX)
		r = -EPROTO;
	return r;
}

/* Reads what the socket holds without blocking. 1 if bytes came, 0 if none,
 * -ECONNRESET on end of stream, other -errno. */
static int read_some(sky_client *c)
{
	if (c->in_cap - c->in_len < 4096) {
		size_t cap = c->in_cap ? c->in_cap * 2 : 8192;
		if (cap > SKY_IN_MAX + 8192)
			cap = SKY_IN_MAX + 8192;
		if (cap <= c->in_len)
			return -EPROTO;
		char *p = realloc(c->in, cap);
		if (!p)
			return -ENOMEM;
		c->in = p;
		c->in_cap = cap;
	}
	union {
		struct cmsghdr h;
		char buf[CMSG_SPACE(sizeof(int) * SKY_MAX_FDS)];
	} cm;
	/* Leave a byte for the terminator handle_input writes. */
	struct iovec iov = { c->in + c->in_len, c->in_cap - c->in_len - 1 };
	struct msghdr mh = { .msg_iov = &iov, .msg_iovlen = 1, .msg_control = cm.buf,
			     .msg_controllen = sizeof(cm.buf) };
	ssize_t n = recvmsg(c->fd, &mh, MSG_DONTWAIT | MSG_CMSG_CLOEXEC);
	if (n < 0)
		return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR ? 0 : -errno;
	for (struct cmsghdr *h = CMSG_FIRSTHDR(&mh); h; h = CMSG_NXTHDR(&mh, h)) {
		if (h->cmsg_level != SOL_SOCKET || h->cmsg_type != SCM_RIGHTS)
			continue;
		size_t k = (h->cmsg_len - CMSG_LEN(0)) / sizeof(int);
		int fds[SKY_MAX_FDS];
		memcpy(fds, CMSG_DATA(h), k * sizeof(int));
		for (size_t i = 0; i < k; i++) {
			if (c->n_fds < SKY_MAX_FDS)
				c->fds[c->n_fds++] = fds[i];
			else
				close(fds[i]);
		}
	}
	if (n == 0)
		return -ECONNRESET;
	c->in_len += (size_t)n;
	return 1;
}

/* Writes queued bytes without blocking. 0 (maybe some left), -errno. */
static int flush_out(sky_client *c)
{
	while (c->out_off < c->out_len) {
		ssize_t n = send(c->fd, c->out + c->out_off, c->out_len - c->out_off,
				 MSG_DONTWAIT | MSG_NOSIGNAL);
		if (n < 0) {
			if (errno == EINTR)
				continue;
			if (errno == EAGAIN || errno == EWOULDBLOCK)
				return 0;
			return -errno;
		}
		c->out_off += (size_t)n;
		c->bytes_sent += (uint64_t)n;
	}
	c->out_off = c->out_len = 0;
	return 0;
}

/* Reads and parses whatever is there; on end of stream or a garbled stream
 * hangs up. Returns 0 or -errno (-ECONNRESET after a hang-up). */
static int pump_input(sky_client *c)
{
	for (;;) {
		int r = read_some(c);
		if (r == 0)
			return 0;
		if (r > 0)
			r = handle_input(c);
		if (r < 0) {
			hang_up(c);
			return r == -ECONNRESET || r == -EPIPE ? -ECONNRESET : r;
		}
	}
}

static int open_socket(const char *path, int *ret_fd)
{
	struct sockaddr_un sa = { .sun_family = AF_UNIX };
	if (strlen(path) >= sizeof(sa.sun_path))
		return -ENAMETOOLONG;
	strcpy(sa.sun_path, path);
	int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
	if (fd < 0)
		return -errno;
	if (connect(fd, (struct sockaddr *)&sa, sizeof(sa)) < 0) {
		int e = -errno;
		close(fd);
		return e;
	}
	*ret_fd = fd;
	return 0;
}

/* Blocks (up to timeout_ms, < 0 forever) until cond holds; the loop that
 * serves the greeting, sky_request() and sky_wait()'s layout change. A
 * request that times out drops the connection (drop_on_timeout). */
static int pump_until(sky_client *c, bool (*cond)(const sky_client *), int timeout_ms,
		      bool drop_on_timeout)
{
	int64_t deadline = timeout_ms < 0 ? -1 : now_ms() + timeout_ms;
	while (!cond(c)) {
		if (c->fd < 0)
			return -ECONNRESET;
		struct pollfd pfd = { c->fd, POLLIN | (c->out_len > c->out_off ? POLLOUT : 0), 0 };
		int n = poll(&pfd, 1, left_ms(deadline));
		if (n < 0 && errno != EINTR)
			return -errno;
		if (n == 0) {
			/* A late reply would be taken for the next request's: drop the line. */
			if (drop_on_timeout) {
				drop_connection(c);
				c->hung_up = true;
			}
			return -ETIMEDOUT;
		}
		if (n < 0)
			continue;
		if (pfd.revents & POLLOUT) {
			int r = flush_out(c);
			if (r < 0) {
				hang_up(c);
				return -ECONNRESET;
			}
		}
		if (pfd.revents & (POLLIN | POLLHUP | POLLERR)) {
			int r = pump_input(c);
			/* "close": the reply came, then the end of the stream */
			if (r < 0 && !cond(c))
				return r;
		}
	}
	return 0;
}

static bool greeted(const sky_client *c)
{
	return c->greeted;
}

static bool sync_done(const sky_client *c)
{
	return c->sync_done;
}

static int do_connect(sky_client *c)
{
	int fd = -1;
	int r = open_socket(c->path, &fd);
	if (r < 0)
		return r;
	c->fd = fd;
	c->hung_up = false;
	c->greeted = false;
	c->bytes_sent = 0;
	r = pump_until(c, greeted, c->timeout_ms, true);
	if (r < 0) {
		drop_connection(c);
		c->hung_up = true;
		/* A daemon that closes before greeting is not a protocol error of ours. */
		return r;
	}
	return 0;
}

int sky_connect(const char *path, sky_client **ret_client)
{
	if (!ret_client)
		return -EINVAL;
	sky_client *c = calloc(1, sizeof(*c));
	if (!c)
		return -ENOMEM;
	c->fd = -1;
	c->timeout_ms = SKY_DEFAULT_TIMEOUT_MS;
	int r;
	if (path) {
		if (strlen(path) >= sizeof(c->path)) {
			r = -ENAMETOOLONG;
			goto fail;
		}
		strcpy(c->path, path);
	} else if ((r = sky_default_path(c->path, sizeof(c->path))) < 0) {
		goto fail;
	}
	r = do_connect(c);
	if (r < 0)
		goto fail;
	events_clear(c);
	*ret_client = c;
	return 0;
fail:
	sky_disconnect(c);
	return r;
}

void sky_disconnect(sky_client *c)
{
	if (!c)
		return;
	drop_connection(c);
	events_clear(c);
	free(c->evq);
	sky_reply_free(c->sync_reply);
	unmap(c);
	free(c->in);
	free(c->out);
	free(c);
}

const char *sky_protocol_version(const sky_client *c)
{
	return c ? c->proto_version : NULL;
}

void sky_set_timeout(sky_client *c, int timeout_ms)
{
	if (c)
		c->timeout_ms = timeout_ms;
}

static int check_line(const char *line)
{
	size_t n = 0;
	for (const unsigned char *p = (const unsigned char *)line; *p; p++, n++)
		if (*p < 0x20 || *p == 0x7f)
			return -EINVAL;
	return n == 0 || n >= SKY_PROTO_LINE_MAX ? -EINVAL : (int)n;
}

static bool is_verb(const char *line, const char *verb)
{
	size_t n = strlen(verb);
	return strncmp(line, verb, n) == 0 && (line[n] == 0 || line[n] == ' ');
}

/* Appends line + newline to the output queue and records what waits for
 * its reply. */
static int queue_line(sky_client *c, const char *line, size_t n, uint64_t userdata, bool sync)
{
	if (c->pend_count >= SKY_MAX_PENDING)
		return -EAGAIN;
	if (c->out_off && c->out_off == c->out_len)
		c->out_off = c->out_len = 0;
	if (c->out_len + n + 1 > SKY_OUT_MAX)
		return -EAGAIN;
	if (!c->out) {
		c->out = malloc(SKY_OUT_MAX);
		if (!c->out)
			return -ENOMEM;
	}
	memcpy(c->out + c->out_len, line, n);
	c->out[c->out_len + n] = '\n';
	c->out_len += n + 1;
	/* "batch" and the lines inside it are answered only by "end". */
	c->unanswered = c->in_batch ? !is_verb(line, "end") : is_verb(line, "batch");
	if (c->in_batch && !c->unanswered)
		c->in_batch = false;
	else if (!c->in_batch && c->unanswered)
		c->in_batch = true;
	if (c->unanswered)
		return 0;
	struct sky_pending *p = &c->pend[(c->pend_head + c->pend_count) % SKY_MAX_PENDING];
	p->userdata = userdata;
	p->sync = sync;
	p->subscribe = is_verb(line, "subscribe");
	c->pend_count++;
	return 0;
}

/* Queues and starts writing a line; if the peer turns out to be gone before
 * any byte of it was delivered, reconnects once and queues it again. */
static int send_line(sky_client *c, const char *line, uint64_t userdata, bool sync)
{
	int n = check_line(line);
	if (n < 0)
		return n;
	for (int attempt = 0;; attempt++) {
		if (c->fd < 0) {
			int r = sky_reconnect(c);
			if (r < 0)
				return r;
		}
		uint64_t before = c->bytes_sent + (c->out_len - c->out_off);
		int r = queue_line(c, line, (size_t)n, userdata, sync);
		if (r < 0)
			return r;
		r = flush_out(c);
		if (r == 0)
			return 0;
		bool delivered = c->bytes_sent > before;
		hang_up(c);
		if (delivered || attempt > 0)
			return -ECONNRESET;
	}
}

int sky_request(sky_client *c, const char *line, sky_reply **ret_reply)
{
	if (!c || !line)
		return -EINVAL;
	sky_reply_free(c->sync_reply);
	c->sync_reply = NULL;
	c->sync_done = false;
	int r = send_line(c, line, 0, true);
	if (r < 0)
		return r;
	if (c->unanswered) {
		if (ret_reply && !(*ret_reply = reply_new()))
			return -ENOMEM;
		return 0;
	}
	r = pump_until(c, sync_done, c->timeout_ms, true);
	if (r < 0)
		return r;
	sky_reply *rep = c->sync_reply;
	c->sync_reply = NULL;
	c->sync_done = false;
	int ack = rep->ack;
	if (ret_reply)
		*ret_reply = rep;
	else
		sky_reply_free(rep);
	return ack;
}

int sky_send(sky_client *c, const char *line, uint64_t userdata)
{
	if (!c || !line)
		return -EINVAL;
	return send_line(c, line, userdata, false);
}

int sky_get_fd(const sky_client *c)
{
	if (!c)
		return -EINVAL;
	return c->fd >= 0 ? c->fd : -ENOTCONN;
}

bool sky_want_write(const sky_client *c)
{
	return c && c->fd >= 0 && c->out_len > c->out_off;
}

int sky_dispatch(sky_client *c, struct sky_event *ret_event)
{
	if (!c || !ret_event)
		return -EINVAL;
	sky_reply_free(c->handed_out);
	c->handed_out = NULL;
	if (c->fd >= 0) {
		if (flush_out(c) < 0)
			hang_up(c);
	}
	if (c->fd >= 0) {
		int r = pump_input(c);
		if (r < 0 && r != -ECONNRESET && !c->ev_count)
			return r;
	}
	if (!c->ev_count)
		return c->fd < 0 && c->hung_up ? -ENOTCONN : 0;
	struct sky_queued q = c->evq[c->ev_head];
	c->ev_head = (c->ev_head + 1) % c->ev_cap;
	c->ev_count--;
	c->handed_out = q.owned;
	*ret_event = q.ev;
	return 1;
}

static int subscribe_line(uint32_t tables, unsigned flags, char *buf, size_t size)
{
	int n = snprintf(buf, size, "subscribe tables=");
	bool first = true;
	for (unsigned i = 0; i < SKY_SHM_MAX_TABLES; i++) {
		if (!(tables & SKY_TABLE_BIT(i)))
			continue;
		n += snprintf(buf + n, size - (size_t)n, "%s%s", first ? "" : ",", table_names[i]);
		first = false;
	}
	if (flags & SKY_SUBSCRIBE_EVENTS)
		n += snprintf(buf + n, size - (size_t)n, " events=1");
	return n;
}

static int subscribe_now(sky_client *c, uint32_t tables, unsigned flags)
{
	char line[256];
	subscribe_line(tables, flags, line, sizeof(line));
	c->map_error = 0;
	int r = sky_request(c, line, NULL);
	if (r != 0)
		return r;
	return c->map_error;
}

int sky_subscribe(sky_client *c, uint32_t tables, unsigned flags)
{
	if (!c || !tables || (tables & ~SKY_TABLES_ALL) || (flags & ~(unsigned)SKY_SUBSCRIBE_EVENTS))
		return -EINVAL;
	int r = subscribe_now(c, tables, flags);
	if (r == 0) {
		c->subscribed = true;
		c->sub_tables = tables;
		c->sub_flags = flags;
	}
	return r;
}

int sky_reconnect(sky_client *c)
{
	if (!c)
		return -EINVAL;
	drop_connection(c);
	events_clear(c);
	c->hung_up = true;
	int r = do_connect(c);
	if (r < 0)
		return r;
	if (c->subscribed) {
		r = subscribe_now(c, c->sub_tables, c->sub_flags);
		if (r != 0) {
			drop_connection(c);
			c->hung_up = true;
			return r > 0 ? -EPROTO : r;
		}
	}
	return 0;
}

/* ---- views ------------------------------------------------------------------ */

const struct sky_shm_header *sky_header(const sky_client *c)
{
	return c ? c->map : NULL;
}

size_t sky_snapshot_size(const sky_client *c)
{
	return c && c->map ? (size_t)c->map->slot_bytes : 0;
}

static const struct sky_shm_slot *slot_at(const sky_client *c, uint32_t i)
{
	return (const struct sky_shm_slot *)((const unsigned char *)c->map + c->map->header_bytes +
					     (uint64_t)i * c->map->slot_bytes);
}

/* Picks the newest slot and its even sequence; -EAGAIN while it is odd. */
static int pick_slot(const sky_client *c, uint32_t *ret_index, uint32_t *ret_seq,
		     uint32_t *ret_gen)
{
	uint32_t gen = __atomic_load_n(&c->map->generation, __ATOMIC_ACQUIRE);
	uint32_t i = __atomic_load_n(&c->map->current_slot, __ATOMIC_ACQUIRE);
	if (i >= c->map->n_slots)
		return -EPROTO;
	uint32_t s = __atomic_load_n(&slot_at(c, i)->seq, __ATOMIC_ACQUIRE);
	if (s & 1u)
		return -EAGAIN;
	*ret_index = i;
	*ret_seq = s;
	*ret_gen = gen;
	return 0;
}

int sky_view_begin(sky_client *c, struct sky_view *ret_view)
{
	if (!c || !ret_view)
		return -EINVAL;
	if (!c->map)
		return -ENOTCONN;
	for (int t = 0; t < SKY_VIEW_TRIES; t++) {
		uint32_t i, seq, gen;
		int r = pick_slot(c, &i, &seq, &gen);
		if (r == -EAGAIN)
			continue;
		if (r < 0)
			return r;
		const struct sky_shm_slot *s = slot_at(c, i);
		ret_view->header = c->map;
		ret_view->slot = s;
		ret_view->slot_base = s;
		ret_view->generation = gen;
		ret_view->valid_tables = __atomic_load_n(&s->valid_tables, __ATOMIC_RELAXED);
		ret_view->slot_index = i;
		ret_view->seq = seq;
		return 0;
	}
	return -EAGAIN;
}

bool sky_view_end(const sky_client *c, const struct sky_view *v)
{
	if (!c || !v || !c->map || v->header != c->map || v->slot_index >= c->map->n_slots)
		return false;
	atomic_thread_fence(memory_order_acquire);
	return __atomic_load_n(&slot_at(c, v->slot_index)->seq, __ATOMIC_RELAXED) == v->seq;
}

int sky_snapshot(sky_client *c, void *buf, size_t size, struct sky_view *ret_view)
{
	if (!c || !buf || !ret_view || ((uintptr_t)buf & 7u))
		return -EINVAL;
	if (!c->map)
		return -ENOTCONN;
	if (size < c->map->slot_bytes)
		return -ENOBUFS;
	for (int t = 0; t < SKY_SNAPSHOT_TRIES; t++) {
		uint32_t i, seq, gen;
		int r = pick_slot(c, &i, &seq, &gen);
		if (r == -EAGAIN)
			continue;
		if (r < 0)
			return r;
		const struct sky_shm_slot *s = slot_at(c, i);
		memcpy(buf, s, c->map->slot_bytes);
		atomic_thread_fence(memory_order_acquire);
		if (__atomic_load_n(&s->seq, __ATOMIC_RELAXED) != seq)
			continue;
		const struct sky_shm_slot *copy = buf;
		ret_view->header = c->map;
		ret_view->slot = copy;
		ret_view->slot_base = buf;
		ret_view->generation = gen;
		ret_view->valid_tables = copy->valid_tables;
		ret_view->slot_index = i;
		ret_view->seq = seq;
		return 0;
	}
	return -EAGAIN;
}

bool sky_view_verify(const struct sky_view *v)
{
	if (!v || !v->header || !v->slot_base)
		return false;
	return skysample_slot_checksum(v->header, v->slot_base) == v->slot->checksum;
}

static bool map_replaced(const sky_client *c)
{
	return c->map != c->old_map;
}

/* The region was superseded: the new one is on its way on the socket with a
 * "layout:" line. Reads the socket (queueing what else comes) until it is
 * mapped or the deadline passes. */
static int follow_layout(sky_client *c, int64_t deadline)
{
	if (c->fd < 0)
		return -ENOTCONN;
	c->old_map = c->map;
	return pump_until(c, map_replaced, deadline < 0 ? -1 : left_ms(deadline), false);
}

int sky_wait(sky_client *c, uint32_t seen, int timeout_ms, uint32_t *ret_generation)
{
	if (!c)
		return -EINVAL;
	if (!c->map)
		return -ENOTCONN;
	int64_t deadline = timeout_ms < 0 ? -1 : now_ms() + timeout_ms;
	for (;;) {
		if (__atomic_load_n(&c->map->superseded, __ATOMIC_ACQUIRE)) {
			int r = follow_layout(c, deadline);
			if (r < 0)
				return r;
		}
		uint32_t *word = (uint32_t *)&c->map->generation;
		uint32_t g = __atomic_load_n(word, __ATOMIC_ACQUIRE);
		if (g != seen && !__atomic_load_n(&c->map->superseded, __ATOMIC_ACQUIRE)) {
			if (ret_generation)
				*ret_generation = g;
			return 0;
		}
		int left = left_ms(deadline);
		if (left == 0)
			return -ETIMEDOUT;
		struct timespec ts = { left / 1000, (long)(left % 1000) * 1000000L };
		/* Shared (not private) futex: the word lives in a shared mapping. */
		long r = syscall(SYS_futex, word, FUTEX_WAIT, seen, left < 0 ? NULL : &ts, NULL, 0);
		if (r < 0 && errno == EINTR)
			return -EINTR;
		if (r < 0 && errno != EAGAIN && errno != ETIMEDOUT)
			return -errno;
	}
}
