/* fdstore_harness.h - plays systemd's file-descriptor store for a test: a
 * NOTIFY_SOCKET of the test's (notify_harness.h) whose FDSTORE=1 and
 * FDSTOREREMOVE=1 messages (FDNAME=) keep and drop fds by name as systemd
 * does, and a start of a program with the stored fds passed the way
 * systemd passes them (LISTEN_FDS, LISTEN_FDNAMES, LISTEN_PID of the child,
 * $FDSTORE). Readiness is READY=1, never a sleep. */
#ifndef SKYD_FDSTORE_HARNESS_H
#define SKYD_FDSTORE_HARNESS_H

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include "notify_harness.h"

#define FDSIM_MAX 8

struct fdsim_entry {
	char name[64];
	int fd;
};

struct fdsim {
	struct notify_sock ns;
	struct fdsim_entry e[FDSIM_MAX];
	int n;
	int max;			/* FileDescriptorStoreMax= */
	int stores, removes;		/* FDSTORE=1 and FDSTOREREMOVE=1 messages seen */
};

/* The NOTIFY_SOCKET in dir, an empty store of max fds. 0 or -errno. */
static inline int fdsim_open(struct fdsim *s, const char *dir, int max)
{
	memset(s, 0, sizeof(*s));
	s->max = max < FDSIM_MAX ? max : FDSIM_MAX;
	return notify_sock_open(&s->ns, dir);
}

static inline void fdsim_close(struct fdsim *s)
{
	for (int i = 0; i < s->n; i++)
		close(s->e[i].fd);
	s->n = 0;
	notify_sock_close(&s->ns);
}

/* The stored fd called name, -1 if none. */
static inline int fdsim_get(const struct fdsim *s, const char *name)
{
	for (int i = 0; i < s->n; i++)
		if (strcmp(s->e[i].name, name) == 0)
			return s->e[i].fd;
	return -1;
}

static inline int fdsim_same_file(int a, int b)
{
	struct stat x, y;

	return fstat(a, &x) == 0 && fstat(b, &y) == 0 && x.st_dev == y.st_dev &&
	       x.st_ino == y.st_ino;
}

/* Applies one message as systemd would: FDSTOREREMOVE=1 drops every fd of
 * that name, FDSTORE=1 keeps each fd that came (an fd of a file already
 * stored is dropped, as is one beyond max). The message's fds are taken. */
static inline void fdsim_apply(struct fdsim *s, struct notify_msg *m)
{
	const char *name = notify_msg_get(m, "FDNAME");
	char nm[64];

	snprintf(nm, sizeof(nm), "%.63s", name ? name : "stored");
	if (notify_msg_get(m, "FDSTOREREMOVE")) {
		s->removes++;
		for (int i = 0; i < s->n;)
			if (strcmp(s->e[i].name, nm) == 0) {
				close(s->e[i].fd);
				s->e[i] = s->e[--s->n];
			} else {
				i++;
			}
	}
	if (notify_msg_get(m, "FDSTORE")) {
		s->stores++;
		for (int k = 0; k < m->n_fds; k++) {
			int dup = 0;
			for (int i = 0; i < s->n; i++)
				dup |= fdsim_same_file(s->e[i].fd, m->fds[k]);
			if (dup || s->n >= s->max) {
				close(m->fds[k]);
				continue;
			}
			memcpy(s->e[s->n].name, nm, sizeof(nm));
			s->e[s->n++].fd = m->fds[k];
		}
		m->n_fds = 0;
	}
	notify_msg_close(m);
}

/* Reads messages, applying them, until one says READY=1 (0), the process
 * behind pidfd exits (-ECHILD) or timeout_ms passes (-ETIMEDOUT). */
static inline int fdsim_wait_ready(struct fdsim *s, int pidfd, int timeout_ms)
{
	long long end = notify_now_ns() + (long long)timeout_ms * 1000000LL;
	struct notify_msg m;

	for (;;) {
		struct pollfd p[2] = { { s->ns.fd, POLLIN, 0 }, { pidfd, POLLIN, 0 } };
		long long left = (end - notify_now_ns()) / 1000000LL;
		if (left <= 0)
			return -ETIMEDOUT;
		if (poll(p, 2, (int)left) < 0)
			return -errno;
		if (p[0].revents & POLLIN) {
			if (notify_sock_recv(&s->ns, 0, &m) < 0)
				continue;
			int ready = notify_msg_get(&m, "READY") != NULL;
			fdsim_apply(s, &m);
			if (ready)
				return 0;
		} else if (p[1].revents & POLLIN) {
			return -ECHILD;
		}
	}
}

/* Reads messages, applying them, until one stores an fd under name (0) or
 * timeout_ms passes (-ETIMEDOUT): a store while the program runs. */
static inline int fdsim_wait_store(struct fdsim *s, const char *name, int timeout_ms)
{
	long long end = notify_now_ns() + (long long)timeout_ms * 1000000LL;
	struct notify_msg m;

	for (;;) {
		long long left = (end - notify_now_ns()) / 1000000LL;
		if (left <= 0)
			return -ETIMEDOUT;
		int r = notify_sock_recv(&s->ns, (int)left, &m);
		if (r < 0)
			return r;
		/* notify_msg_get's value lives until its next call. */
		const char *n = notify_msg_get(&m, "FDNAME");
		int hit = n && strcmp(n, name) == 0 && notify_msg_get(&m, "FDSTORE");
		fdsim_apply(s, &m);
		if (hit)
			return 0;
	}
}

/* Starts argv (argv[0] a path) with stderr appended to log, NOTIFY_SOCKET
 * and FDSTORE set, and the stored fds from 3 on, named in LISTEN_FDNAMES,
 * LISTEN_PID the child's. The child's pid, *ret_pidfd a pidfd of it. */
static inline pid_t fdsim_spawn(struct fdsim *s, const char *const *argv, const char *log,
				int *ret_pidfd)
{
	pid_t pid = fork();

	if (pid == 0) {
		char names[FDSIM_MAX * 65] = "", v[32];
		int moved[FDSIM_MAX], fd = open(log, O_WRONLY | O_CREAT | O_APPEND, 0600);
		if (fd >= 0)
			dup2(fd, 2);
		/* Out of the way of 3.. first, then into place (dup2 clears CLOEXEC). */
		for (int i = 0; i < s->n; i++)
			moved[i] = fcntl(s->e[i].fd, F_DUPFD_CLOEXEC, 64);
		for (int i = 0; i < s->n; i++) {
			dup2(moved[i], 3 + i);
			snprintf(names + strlen(names), sizeof(names) - strlen(names), "%s%s",
				 i ? ":" : "", s->e[i].name);
		}
		setenv("NOTIFY_SOCKET", s->ns.path, 1);
		snprintf(v, sizeof(v), "%d", s->max);
		setenv("FDSTORE", v, 1);
		if (s->n) {
			snprintf(v, sizeof(v), "%d", s->n);
			setenv("LISTEN_FDS", v, 1);
			setenv("LISTEN_FDNAMES", names, 1);
			snprintf(v, sizeof(v), "%d", (int)getpid());
			setenv("LISTEN_PID", v, 1);
		}
		execv(argv[0], (char *const *)argv);
		_exit(127);
	}
	*ret_pidfd = pid > 0 ? (int)syscall(SYS_pidfd_open, pid, 0) : -1;
	return pid;
}

#endif
