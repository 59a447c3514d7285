/* loop.h - the daemon's one event loop: fds on epoll, signals through a
 * signalfd, timers on CLOCK_MONOTONIC through timerfds. Nothing in a
 * callback may block.
 *
 * Handles are owned by the loop. Deleting one (loop_io_del, loop_timer_del)
 * is safe from inside any callback, its own included: the handle is marked
 * dead, never called again, and freed once the current dispatch is over.
 * loop_io_retire does the same for an object whose callbacks may still be
 * on the stack: the loop releases it then, never under its own caller.
 */
#ifndef SKYD_LOOP_H
#define SKYD_LOOP_H

#include <stdint.h>
#include <sys/epoll.h>

struct loop;
struct loop_io;
struct loop_timer;

typedef void (*loop_io_fn)(void *ctx, uint32_t events);
typedef void (*loop_timer_fn)(void *ctx);
typedef void (*loop_signal_fn)(void *ctx, int signo);

int loop_new(struct loop **ret);
/* Frees the loop and every handle still registered; fds stay open (their
 * owners close them). */
void loop_free(struct loop *l);

/* Watches fd for events (EPOLLIN, EPOLLOUT, EPOLLET...). The fd stays owned
 * by the caller and must stay open until loop_io_del. */
int loop_io_add(struct loop *l, int fd, uint32_t events, loop_io_fn fn, void *ctx,
		struct loop_io **ret);
int loop_io_mod(struct loop_io *io, uint32_t events);
void loop_io_del(struct loop_io *io);
/* Deletes io like loop_io_del and calls release(ctx) once the current
 * dispatch is over (or from loop_free): the owner marks its object dead
 * and leaves the freeing to the loop, so that a handler that caused the
 * drop may go on reading the object until it returns. */
void loop_io_retire(struct loop_io *io, void (*release)(void *ctx));

int loop_timer_add(struct loop *l, loop_timer_fn fn, void *ctx, struct loop_timer **ret);
/* One shot after delay_ns on the monotonic clock; 0 disarms. */
int loop_timer_arm(struct loop_timer *t, uint64_t delay_ns);
void loop_timer_del(struct loop_timer *t);

/* Blocks the given signals and delivers them to fn through a signalfd.
 * Call once, before any thread is started. */
int loop_signals(struct loop *l, const int *signals, int n, loop_signal_fn fn, void *ctx);

/* Dispatches until loop_quit. Returns 0, or -errno if epoll fails. */
int loop_run(struct loop *l);
void loop_quit(struct loop *l);

/* CLOCK_MONOTONIC in nanoseconds. */
uint64_t loop_now_ns(void);

#endif
