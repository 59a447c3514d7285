/* loop.c - epoll dispatch with deferred deletion, signalfd and timerfds. */
#include "loop.h"

#include <assert.h>
#include <errno.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <sys/signalfd.h>
#include <sys/timerfd.h>
#include <time.h>
#include <unistd.h>

struct loop_io {
	struct loop *loop;
	int fd;
	int owns_fd;			/* timerfd and signalfd belong to the loop */
	int dead;
	loop_io_fn fn;
	void *ctx;
	void (*release)(void *ctx);	/* loop_io_retire: frees ctx when reaped */
	struct loop_io *next;		/* all handles, for loop_free and reaping */
};

struct loop_timer {
	struct loop_io *io;
	loop_timer_fn fn;
	void *ctx;
};

struct loop {
	int epoll_fd;
	int quit;
	struct loop_io *ios;
	struct loop_io *signal_io;
	loop_signal_fn signal_fn;
	void *signal_ctx;
	int n_dead;
};

uint64_t loop_now_ns(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

int loop_new(struct loop **ret)
{
	struct loop *l = calloc(1, sizeof(*l));

	if (!l)
		return -ENOMEM;
	l->epoll_fd = epoll_create1(EPOLL_CLOEXEC);
	if (l->epoll_fd < 0) {
		int e = errno;
		free(l);
		return -e;
	}
	*ret = l;
	return 0;
}

static void io_destroy(struct loop_io *io)
{
	if (io->release)
		io->release(io->ctx);
	if (io->owns_fd && io->fd >= 0)
		close(io->fd);
	free(io);
}

static void reap(struct loop *l)
{
	struct loop_io **pp = &l->ios;

	if (!l->n_dead)
		return;
	while (*pp) {
		struct loop_io *io = *pp;
		if (io->dead) {
			*pp = io->next;
			io_destroy(io);
		} else {
			pp = &io->next;
		}
	}
	l->n_dead = 0;
}

void loop_free(struct loop *l)
{
	if (!l)
		return;
	while (l->ios) {
		struct loop_io *io = l->ios;
		l->ios = io->next;
		io_destroy(io);
	}
	if (l->epoll_fd >= 0)
		close(l->epoll_fd);
	free(l);
}

int loop_io_add(struct loop *l, int fd, uint32_t events, loop_io_fn fn, void *ctx,
		struct loop_io **ret)
{
	struct loop_io *io = calloc(1, sizeof(*io));
	struct epoll_event ev = { .events = events };

	if (!io)
		return -ENOMEM;
	io->loop = l;
	io->fd = fd;
	io->fn = fn;
	io->ctx = ctx;
	ev.data.ptr = io;
	if (epoll_ctl(l->epoll_fd, EPOLL_CTL_ADD, fd, &ev) < 0) {
		int e = errno;
		free(io);
		return -e;
	}
	io->next = l->ios;
	l->ios = io;
	if (ret)
		*ret = io;
	return 0;
}

int loop_io_mod(struct loop_io *io, uint32_t events)
{
	struct epoll_event ev = { .events = events, .data.ptr = io };

	assert(!io->dead);
	return epoll_ctl(io->loop->epoll_fd, EPOLL_CTL_MOD, io->fd, &ev) < 0 ? -errno : 0;
}

void loop_io_del(struct loop_io *io)
{
	if (!io || io->dead)
		return;
	epoll_ctl(io->loop->epoll_fd, EPOLL_CTL_DEL, io->fd, NULL);
	io->dead = 1;
	io->loop->n_dead++;
}

void loop_io_retire(struct loop_io *io, void (*release)(void *ctx))
{
	if (!io)
		return;
	loop_io_del(io);
	io->release = release;
}

static void timer_ready(void *ctx, uint32_t events)
{
	struct loop_timer *t = ctx;
	uint64_t expirations;

	if (read(t->io->fd, &expirations, sizeof(expirations)) != sizeof(expirations))
		return;
	t->fn(t->ctx);
}

int loop_timer_add(struct loop *l, loop_timer_fn fn, void *ctx, struct loop_timer **ret)
{
	struct loop_timer *t = calloc(1, sizeof(*t));
	int fd, r;

	if (!t)
		return -ENOMEM;
	fd = timerfd_create(CLOCK_MONOTONIC, TFD_CLOEXEC | TFD_NONBLOCK);
	if (fd < 0) {
		r = -errno;
		free(t);
		return r;
	}
	t->fn = fn;
	t->ctx = ctx;
	r = loop_io_add(l, fd, EPOLLIN, timer_ready, t, &t->io);
	if (r < 0) {
		close(fd);
		free(t);
		return r;
	}
	t->io->owns_fd = 1;
	*ret = t;
	return 0;
}

int loop_timer_arm(struct loop_timer *t, uint64_t delay_ns)
{
	struct itimerspec its = { 0 };

	its.it_value.tv_sec = (time_t)(delay_ns / 1000000000u);
	its.it_value.tv_nsec = (long)(delay_ns % 1000000000u);
	return timerfd_settime(t->io->fd, 0, &its, NULL) < 0 ? -errno : 0;
}

void loop_timer_del(struct loop_timer *t)
{
	if (!t)
		return;
	/* The io outlives t only as a dead handle, never called again. */
	loop_io_del(t->io);
	free(t);
}

static void signal_ready(void *ctx, uint32_t events)
{
	struct loop *l = ctx;
	struct signalfd_siginfo si;

	while (read(l->signal_io->fd, &si, sizeof(si)) == sizeof(si))
		l->signal_fn(l->signal_ctx, (int)si.ssi_signo);
}

int loop_signals(struct loop *l, const int *signals, int n, loop_signal_fn fn, void *ctx)
{
	sigset_t set;
	int fd, r;

	sigemptyset(&set);
	for (int i = 0; i < n; i++)
		sigaddset(&set, signals[i]);
	if (sigprocmask(SIG_BLOCK, &set, NULL) < 0)
		return -errno;
	fd = signalfd(-1, &set, SFD_CLOEXEC | SFD_NONBLOCK);
	if (fd < 0)
		return -errno;
	l->signal_fn = fn;
	l->signal_ctx = ctx;
	r = loop_io_add(l, fd, EPOLLIN, signal_ready, l, &l->signal_io);
	if (r < 0) {
		close(fd);
		return r;
	}
	l->signal_io->owns_fd = 1;
	return 0;
}

int loop_run(struct loop *l)
{
	struct epoll_event evs[64];

	l->quit = 0;
	while (!l->quit) {
		int n = epoll_wait(l->epoll_fd, evs, 64, -1);
		if (n < 0) {
			if (errno == EINTR)
				continue;
			return -errno;
		}
		for (int i = 0; i < n && !l->quit; i++) {
			struct loop_io *io = evs[i].data.ptr;
			if (!io->dead)
				io->fn(io->ctx, evs[i].events);
		}
		reap(l);
	}
	return 0;
}

void loop_quit(struct loop *l)
{
	l->quit = 1;
}
