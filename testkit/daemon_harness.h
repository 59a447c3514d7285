/* daemon_harness.h - starts the real skyd on a private socket in a fresh
 * directory and talks to it as a client would; shared by the integration
 * tests and latbench. Readiness comes from skyd's sd_notify("READY=1") on a socket of
 * ours, never from a sleep. */
#ifndef SKYD_DAEMON_HARNESS_H
#define SKYD_DAEMON_HARNESS_H

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "eng.h"

#ifndef HARNESS_TIMEOUT_MS
#define HARNESS_TIMEOUT_MS 60000
#endif

/* Now on the monotonic clock, in milliseconds: for the tests' deadlines. */
static inline int64_t harness_now_ms(void)
{
	struct timespec t;
	clock_gettime(CLOCK_MONOTONIC, &t);
	return (int64_t)t.tv_sec * 1000 + t.tv_nsec / 1000000;
}

/* Small tables: these tests are about the service, not the tables. */
#define HARNESS_SMALL                                                             \
	"transmittance_width=64", "transmittance_height=16", "transmittance_steps=16", \
	"multiscatter_width=8", "multiscatter_height=8", "multiscatter_steps=8",     \
	"multiscatter_dirs=2", "skyview_width=32", "skyview_height=16",              \
	"skyview_steps=8", "aerial_width=8", "aerial_height=8", "aerial_depth=4"

struct daemon {
	pid_t pid;
	int pidfd;
	char dir[128];
	char sock[192];
	char log[192];
};

/* Exits 77 (skipped) when no Vulkan device can be opened. */
static inline void harness_need_device(void)
{
	char err[256];
	struct eng *e;

	if (eng_new(NULL, err, sizeof(err), &e) < 0) {
		printf("skipped: no Vulkan device: %s\n", err);
		exit(77);
	}
	eng_free(e);
}

static inline int harness_mkdtemp(char *buf, size_t size)
{
	const char *tmp = getenv("TMPDIR");
	snprintf(buf, size, "%s/skyd-test-XXXXXX", tmp && *tmp ? tmp : "/tmp");
	return mkdtemp(buf) ? 0 : -errno;
}

/* Starts skyd with --socket in a new directory and args (NULL-terminated)
 * appended; returns once skyd said READY=1. 0 or -1 (skyd died: see log). */
static inline int daemon_start_in(struct daemon *d, const char *dir, const char *const *args)
{
	char notify[256], buf[256];
	struct sockaddr_un sa = { .sun_family = AF_UNIX };
	const char *argv[64];
	int n = 0, ns;

	/* dir may be d->dir itself (a restart): snprintf must not overlap. */
	if (dir != d->dir)
		snprintf(d->dir, sizeof(d->dir), "%s", dir);
	snprintf(d->sock, sizeof(d->sock), "%s/control", d->dir);
	snprintf(d->log, sizeof(d->log), "%s/skyd.log", d->dir);
	snprintf(notify, sizeof(notify), "%s/notify", d->dir);
	unlink(notify);
	if (strlen(notify) >= sizeof(sa.sun_path))
		return -1;
	memcpy(sa.sun_path, notify, strlen(notify) + 1);
	ns = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
	if (ns < 0 || bind(ns, (struct sockaddr *)&sa, sizeof(sa)) < 0)
		return -1;
	argv[n++] = SKYD_BINARY;
	argv[n++] = "--socket";
	argv[n++] = d->sock;
	for (int i = 0; args && args[i] && n < 62; i++)
		argv[n++] = args[i];
	argv[n] = NULL;
	d->pid = fork();
	if (d->pid == 0) {
		int fd = open(d->log, O_WRONLY | O_CREAT | O_APPEND, 0600);
		if (fd >= 0)
			dup2(fd, 2);
		setenv("NOTIFY_SOCKET", notify, 1);
		execv(argv[0], (char *const *)argv);
		_exit(127);
	}
	d->pidfd = (int)syscall(SYS_pidfd_open, d->pid, 0);
	struct pollfd p[2] = { { ns, POLLIN, 0 }, { d->pidfd, POLLIN, 0 } };
	for (;;) {
		if (poll(p, 2, HARNESS_TIMEOUT_MS) <= 0 || (p[1].revents & POLLIN)) {
			close(ns);
			fprintf(stderr, "skyd did not get ready; its log %s:\n", d->log);
			snprintf(buf, sizeof(buf), "cat '%s' >&2", d->log);
			(void)!system(buf);
			return -1;
		}
		ssize_t k = recv(ns, buf, sizeof(buf) - 1, 0);
		if (k > 0) {
			buf[k] = 0;
			if (strstr(buf, "READY=1"))
				break;
		}
	}
	close(ns);
	return 0;
}

static inline int daemon_start(struct daemon *d, const char *const *args)
{
	char dir[128];

	if (harness_mkdtemp(dir, sizeof(dir)) < 0)
		return -1;
	return daemon_start_in(d, dir, args);
}

/* Sends sig and reaps skyd; returns its wait status. */
static inline int daemon_stop(struct daemon *d, int sig)
{
	int status = 0;

	if (d->pid <= 0)
		return 0;
	kill(d->pid, sig);
	waitpid(d->pid, &status, 0);
	close(d->pidfd);
	d->pid = 0;
	return status;
}

static inline void daemon_cleanup(struct daemon *d)
{
	char cmd[256];

	daemon_stop(d, SIGTERM);
	snprintf(cmd, sizeof(cmd), "rm -rf '%s'", d->dir);
	(void)!system(cmd);
}

/* A connection: a line reader over recvmsg that keeps fds that come along. */
struct conn {
	int fd;
	char buf[1 << 16];
	size_t len;
	int fds[16];
	int n_fds;
	uint64_t event_generation;	/* newest changed: seen */
	int layouts;			/* layout: lines seen */
	char event_tables[96];		/* the tables= of the newest changed: */
};

static inline int conn_raw(const char *path)
{
	struct sockaddr_un sa = { .sun_family = AF_UNIX };
	int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);

	if (strlen(path) >= sizeof(sa.sun_path)) {
		if (fd >= 0)
			close(fd);
		return -1;
	}
	memcpy(sa.sun_path, path, strlen(path) + 1);
	if (fd < 0 || connect(fd, (struct sockaddr *)&sa, sizeof(sa)) < 0) {
		if (fd >= 0)
			close(fd);
		return -1;
	}
	return fd;
}

/* One line without its newline into line; -1 on EOF, error or timeout. */
static inline int conn_line(struct conn *c, char *line, size_t size)
{
	for (;;) {
		char *nl = memchr(c->buf, '\n', c->len);
		if (nl) {
			size_t n = (size_t)(nl - c->buf);
			snprintf(line, size, "%.*s", (int)n, c->buf);
			memmove(c->buf, nl + 1, c->len - n - 1);
			c->len -= n + 1;
			return (int)n;
		}
		struct pollfd p = { c->fd, POLLIN, 0 };
		if (poll(&p, 1, HARNESS_TIMEOUT_MS) <= 0)
			return -1;
		union {
			char b[CMSG_SPACE(sizeof(int) * 4)];
			struct cmsghdr a;
		} u;
		struct iovec iov = { c->buf + c->len, sizeof(c->buf) - c->len };
		struct msghdr mh = { .msg_iov = &iov, .msg_iovlen = 1, .msg_control = u.b,
				     .msg_controllen = sizeof(u.b) };
		ssize_t k = recvmsg(c->fd, &mh, MSG_CMSG_CLOEXEC);
		if (k <= 0)
			return -1;
		for (struct cmsghdr *cm = CMSG_FIRSTHDR(&mh); cm; cm = CMSG_NXTHDR(&mh, cm))
			if (cm->cmsg_level == SOL_SOCKET && cm->cmsg_type == SCM_RIGHTS) {
				int nf = (int)((cm->cmsg_len - CMSG_LEN(0)) / sizeof(int));
				for (int i = 0; i < nf && c->n_fds < 16; i++)
					memcpy(&c->fds[c->n_fds++], CMSG_DATA(cm) + i * sizeof(int), sizeof(int));
			}
		c->len += (size_t)k;
	}
}

static inline int conn_open(struct conn *c, const char *path)
{
	char line[256];

	memset(c, 0, sizeof(*c));
	c->fd = conn_raw(path);
	if (c->fd < 0 || conn_line(c, line, sizeof(line)) < 0 || strncmp(line, "OK skyd ", 8) != 0)
		return -1;
	return 0;
}

static inline void conn_close(struct conn *c)
{
	for (int i = 0; i < c->n_fds; i++)
		close(c->fds[i]);
	if (c->fd >= 0)
		close(c->fd);
	c->fd = -1;
	c->n_fds = 0;
}

static inline void conn_note_event(struct conn *c, const char *line)
{
	const char *g = strstr(line, "generation=");
	if (!g)
		return;
	uint64_t gen = strtoull(g + 11, NULL, 10);
	if (strncmp(line, "changed: ", 9) == 0 && gen > c->event_generation) {
		const char *t = strstr(line, "tables=");
		c->event_generation = gen;
		snprintf(c->event_tables, sizeof(c->event_tables), "%s", t ? t + 7 : "");
	}
	if (strncmp(line, "layout: ", 8) == 0)
		c->layouts++;
}

static inline int is_event_line(const char *line)
{
	return !strncmp(line, "changed: ", 9) || !strncmp(line, "layout: ", 8) ||
	       !strncmp(line, "failed: ", 8);
}

/* Sends req (a newline is added) and collects the reply's lines into reply
 * (event lines are noted, not kept). Returns 0 for OK, the ACK code, or -1. */
static inline int conn_request(struct conn *c, const char *req, char *reply, size_t size)
{
	char line[8192];
	size_t o = 0;

	if (reply && size)
		reply[0] = 0;
	size_t n = strlen(req);
	char *msg = malloc(n + 1);
	memcpy(msg, req, n);
	msg[n] = '\n';
	ssize_t w = send(c->fd, msg, n + 1, MSG_NOSIGNAL);
	free(msg);
	if (w != (ssize_t)(n + 1))
		return -1;
	for (;;) {
		if (conn_line(c, line, sizeof(line)) < 0)
			return -1;
		if (is_event_line(line)) {
			conn_note_event(c, line);
			continue;
		}
		if (reply && o < size)
			o += (size_t)snprintf(reply + o, size - o, "%s\n", line);
		if (strcmp(line, "OK") == 0)
			return 0;
		if (strncmp(line, "ACK [", 5) == 0)
			return atoi(line + 5);
	}
}

/* The value of "key: value" in a reply, or NULL. */
static inline const char *reply_value(const char *reply, const char *key, char *buf, size_t size)
{
	size_t k = strlen(key);

	for (const char *p = reply; p && *p;) {
		const char *e = strchr(p, '\n');
		size_t n = e ? (size_t)(e - p) : strlen(p);
		if (n > k + 1 && !strncmp(p, key, k) && p[k] == ':' && p[k + 1] == ' ') {
			snprintf(buf, size, "%.*s", (int)(n - k - 2), p + k + 2);
			return buf;
		}
		p = e ? e + 1 : NULL;
	}
	return NULL;
}

static inline uint64_t reply_u64(const char *reply, const char *key)
{
	char buf[64];
	return reply_value(reply, key, buf, sizeof(buf)) ? strtoull(buf, NULL, 10) : UINT64_MAX;
}

/* Reads event lines until a changed: line of generation >= gen. */
static inline int conn_wait_generation(struct conn *c, uint64_t gen)
{
	char line[1024];

	while (c->event_generation < gen) {
		if (conn_line(c, line, sizeof(line)) < 0)
			return -1;
		conn_note_event(c, line);
	}
	return 0;
}

#endif
