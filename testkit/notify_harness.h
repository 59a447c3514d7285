/* notify_harness.h - plays systemd's side of sd_notify for a test: an
 * AF_UNIX datagram socket the test owns (NOTIFY_SOCKET points at it) that
 * reads each message with its sender's credentials and any fds passed
 * along (FDSTORE=1), and waits for a given assignment without a sleep. */
#ifndef SKYD_NOTIFY_HARNESS_H
#define SKYD_NOTIFY_HARNESS_H

#include <errno.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/types.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>

#define NOTIFY_MSG_MAX 4096
#define NOTIFY_FDS_MAX 16

struct notify_sock {
	int fd;
	char path[108];
};

/* One datagram: its text (newline-separated VAR=value lines), the sender's
 * pid from SCM_CREDENTIALS, the fds that came with it (now the test's to
 * close: notify_msg_close) and when it arrived (CLOCK_MONOTONIC, ns). */
struct notify_msg {
	char text[NOTIFY_MSG_MAX];
	pid_t pid;
	int fds[NOTIFY_FDS_MAX];
	int n_fds;
	long long at_ns;
};

static inline long long notify_now_ns(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_MONOTONIC, &ts);
	return ts.tv_sec * 1000000000LL + ts.tv_nsec;
}

/* Binds dir/notify (replacing a stale one) with SO_PASSCRED on; the path
 * is what NOTIFY_SOCKET must say. 0 or -errno. */
static inline int notify_sock_open(struct notify_sock *ns, const char *dir)
{
	struct sockaddr_un sa = { .sun_family = AF_UNIX };
	int one = 1;

	ns->fd = -1;
	if ((size_t)snprintf(ns->path, sizeof(ns->path), "%s/notify", dir) >= sizeof(ns->path) ||
	    strlen(ns->path) >= sizeof(sa.sun_path))
		return -ENAMETOOLONG;
	memcpy(sa.sun_path, ns->path, strlen(ns->path) + 1);
	unlink(ns->path);
	ns->fd = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
	if (ns->fd < 0)
		return -errno;
	if (setsockopt(ns->fd, SOL_SOCKET, SO_PASSCRED, &one, sizeof(one)) < 0 ||
	    bind(ns->fd, (struct sockaddr *)&sa, sizeof(sa)) < 0) {
		int e = -errno;
		close(ns->fd);
		ns->fd = -1;
		return e;
	}
	return 0;
}

static inline void notify_sock_close(struct notify_sock *ns)
{
	if (ns->fd >= 0)
		close(ns->fd);
	ns->fd = -1;
	unlink(ns->path);
}

static inline void notify_msg_close(struct notify_msg *m)
{
	for (int i = 0; i < m->n_fds; i++)
		close(m->fds[i]);
	m->n_fds = 0;
}

/* The next datagram within timeout_ms: 0, -ETIMEDOUT, or -errno. */
static inline int notify_sock_recv(struct notify_sock *ns, int timeout_ms, struct notify_msg *ret)
{
	struct pollfd p = { ns->fd, POLLIN, 0 };
	union {
		char b[CMSG_SPACE(sizeof(struct ucred)) + CMSG_SPACE(sizeof(int) * NOTIFY_FDS_MAX)];
		struct cmsghdr align;
	} u;
	struct iovec iov = { ret->text, sizeof(ret->text) - 1 };
	struct msghdr mh = { .msg_iov = &iov, .msg_iovlen = 1, .msg_control = u.b,
			     .msg_controllen = sizeof(u.b) };
	int r = poll(&p, 1, timeout_ms);

	if (r < 0)
		return -errno;
	if (r == 0)
		return -ETIMEDOUT;
	ssize_t k = recvmsg(ns->fd, &mh, MSG_CMSG_CLOEXEC);
	if (k < 0)
		return -errno;
	ret->text[k] = 0;
	ret->pid = 0;
	ret->n_fds = 0;
	ret->at_ns = notify_now_ns();
	for (struct cmsghdr *cm = CMSG_FIRSTHDR(&mh); cm; cm = CMSG_NXTHDR(&mh, cm)) {
		if (cm->cmsg_level != SOL_SOCKET)
			continue;
		if (cm->cmsg_type == SCM_CREDENTIALS) {
			struct ucred cred;
			memcpy(&cred, CMSG_DATA(cm), sizeof(cred));
			ret->pid = cred.pid;
		} else if (cm->cmsg_type == SCM_RIGHTS) {
			int nf = (int)((cm->cmsg_len - CMSG_LEN(0)) / sizeof(int));
			for (int i = 0; i < nf && ret->n_fds < NOTIFY_FDS_MAX; i++)
				memcpy(&ret->fds[ret->n_fds++], CMSG_DATA(cm) + i * sizeof(int),
				       sizeof(int));
		}
	}
	return 0;
}

/* The value of VAR in m (a pointer into a static copy, "" if VAR= is
 * empty), or NULL when m does not assign it. */
static inline const char *notify_msg_get(const struct notify_msg *m, const char *var)
{
	static char value[NOTIFY_MSG_MAX];
	size_t n = strlen(var);

	for (const char *l = m->text; *l;) {
		const char *nl = strchr(l, '\n');
		size_t len = nl ? (size_t)(nl - l) : strlen(l);
		if (len > n && strncmp(l, var, n) == 0 && l[n] == '=') {
			snprintf(value, sizeof(value), "%.*s", (int)(len - n - 1), l + n + 1);
			return value;
		}
		if (!nl)
			break;
		l = nl + 1;
	}
	return NULL;
}

/* Reads datagrams until one assigns VAR (to value, or to anything when
 * value is NULL), within timeout_ms overall; the others are dropped (their
 * fds closed). 0 with it in ret, or -ETIMEDOUT / -errno. */
static inline int notify_sock_wait(struct notify_sock *ns, const char *var, const char *value,
				   int timeout_ms, struct notify_msg *ret)
{
	long long end = notify_now_ns() + (long long)timeout_ms * 1000000LL;

	for (;;) {
		long long left_ms = (end - notify_now_ns()) / 1000000LL;
		if (left_ms < 0)
			return -ETIMEDOUT;
		int r = notify_sock_recv(ns, (int)left_ms, ret);
		if (r < 0)
			return r;
		const char *v = notify_msg_get(ret, var);
		if (v && (!value || strcmp(v, value) == 0))
			return 0;
		notify_msg_close(ret);
	}
}

#endif
