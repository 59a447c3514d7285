/* ctl.c - the control server: the listening socket, accepting with a
 * pause while the process is out of fds, and the events every client hears
 * of (layout:, changed:, failed:). */
#include "ctl_internal.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "log.h"
#include "loop.h"
#include "pub.h"
#include "srv.h"

/* The tables in use: what connections subscribed to and what they sampled.
 * srv computes this and its dependencies, nothing else. */
void ctl_update_demand(struct ctl *ctl)
{
	uint32_t demand = 0;

	for (struct client *k = ctl->clients; k; k = k->next)
		demand |= k->sub_tables | k->sample_tables;
	srv_set_demand(ctl->srv, demand);
}

/* Events ---------------------------------------------------------------- */

/* srv's listener: a new generation. */
static void on_published(void *ctx, uint64_t generation, uint32_t tables, int new_region)
{
	struct ctl *ctl = ctx;
	struct pub *p = srv_pub(ctl->srv);
	struct client *c, *next;
	char names[64], line[160];

	state_format_all_tables(tables, names, sizeof(names));
	for (c = ctl->clients; c; c = next) {
		next = c->next;
		if (new_region && c->sub_tables) {
			int n = snprintf(line, sizeof(line), "layout: generation=%llu bytes=%llu\n",
					 (unsigned long long)generation,
					 (unsigned long long)pub_bytes(p));
			if (ctl_client_queue(c, line, (size_t)n, pub_fd(p)) < 0)
				continue;
		}
		if (c->sub_events) {
			int n = snprintf(line, sizeof(line), "changed: generation=%llu tables=%s\n",
					 (unsigned long long)generation, names);
			if (ctl_client_queue(c, line, (size_t)n, -1) < 0)
				continue;
		}
		if (c->out_head)
			ctl_client_flush(c);
	}
	ctl_resume_deferred(ctl, 0);
}

/* srv's listener: a computation failed. */
static void on_failed(void *ctx, uint64_t generation, const char *message)
{
	struct ctl *ctl = ctx;
	struct client *c, *next;
	char line[400];
	int n = snprintf(line, sizeof(line), "failed: generation=%llu message=", (unsigned long long)generation);

	/* The message is free text: keep it on one line, spaces as '_'. */
	for (const char *m = message; *m && n < (int)sizeof(line) - 2; m++)
		line[n++] = (*m > ' ' && *m < 0x7f) ? *m : '_';
	line[n++] = '\n';
	for (c = ctl->clients; c; c = next) {
		next = c->next;
		if (c->sub_events && ctl_client_queue(c, line, (size_t)n, -1) == 0)
			ctl_client_flush(c);
	}
	ctl_resume_deferred(ctl, 1);
}

/* Accepting ------------------------------------------------------------- */

static void accept_resume(void *ctx)
{
	struct ctl *ctl = ctx;

	if (ctl->accept_paused) {
		ctl->accept_paused = 0;
		loop_io_mod(ctl->listen_io, EPOLLIN);
	}
}

/* Logs a refused connection from cred's uid if that uid's last such line
 * is a minute old or more; otherwise counts it for that line. */
static void refusal_log(struct ctl *ctl, const struct ucred *cred)
{
	struct ctl_refusals *rf = &ctl->refusals;
	struct ctl_refusal *e = NULL, *free_e = NULL;
	uint64_t now = loop_now_ns();

	for (int i = 0; i < CTL_REFUSAL_UIDS; i++) {
		struct ctl_refusal *k = &rf->uids[i];
		if (k->logged_ns && k->uid == cred->uid)
			e = k;
		else if (!free_e && (!k->logged_ns || now - k->logged_ns >= CTL_REFUSAL_LOG_NS))
			free_e = k;
	}
	if (e && now - e->logged_ns < CTL_REFUSAL_LOG_NS) {
		e->unlogged++;
		return;
	}
	if (!e && !free_e) {
		rf->unlisted++;
		return;
	}
	uint64_t before = e ? e->unlogged : 0;
	if (!e) {
		e = free_e;
		e->uid = cred->uid;
	}
	char more[160] = "";
	int n = 0;
	if (before)
		n = snprintf(more, sizeof(more), "; %llu more from this uid since its last line",
			     (unsigned long long)before);
	if (rf->unlisted)
		snprintf(more + n, sizeof(more) - (size_t)n, "; %llu from other uids not logged",
			 (unsigned long long)rf->unlisted);
	log_warning("connection from uid %d (pid %d) refused: %d clients, max_connections = %u (one line per uid a minute)%s",
		    (int)cred->uid, (int)cred->pid, ctl->n_clients, ctl->roles.max_connections, more);
	e->logged_ns = now ? now : 1;
	e->unlogged = 0;
	rf->unlisted = 0;
}

/* Places at the end of max_connections that only controllers may take,
 * so that a flood of readers cannot lock the controllers out. */
static int controller_reserve(const struct ctl *ctl)
{
	return (int)(ctl->roles.max_connections / 16);
}

/* Past max_connections (or into the controllers' reserve, for a reader):
 * one ACK line, then the connection closes. Those already connected do
 * not notice. */
static void refuse_connection(struct ctl *ctl, int fd, const struct ucred *cred, int reserved)
{
	char line[200];
	int n = snprintf(line, sizeof(line),
			 "ACK [%d] {connect} too many connections (max_connections = %u%s); try again later\n",
			 SKY_ACK_LIMIT, ctl->roles.max_connections,
			 reserved ? ", the last places kept for controllers" : "");

	(void)!send(fd, line, (size_t)n, MSG_NOSIGNAL | MSG_DONTWAIT);
	/* Logged before the close, so the peer's EOF comes after the line. */
	refusal_log(ctl, cred);
	close(fd);
}

static void accept_ready(void *ctx, uint32_t events)
{
	struct ctl *ctl = ctx;

	for (int i = 0; i < 64; i++) {
		int fd = accept4(ctl->listen_fd, NULL, NULL, SOCK_CLOEXEC | SOCK_NONBLOCK);
		if (fd < 0) {
			if (errno == EMFILE || errno == ENFILE || errno == ENOBUFS || errno == ENOMEM) {
				/* Out of fds: stop accepting until a client leaves or
				 * 100 ms pass, instead of spinning on the ready socket.
				 * Said once, not on every retry. */
				if (!ctl->accept_warned)
					log_warning("accept: %s; pausing until a client leaves (retrying every 100 ms)",
						    strerror(errno));
				ctl->accept_warned = 1;
				ctl->accept_paused = 1;
				loop_io_mod(ctl->listen_io, 0);
				loop_timer_arm(ctl->accept_timer, 100000000u);
			}
			return;
		}
		if (ctl->accept_warned) {
			log_info("accepting connections again");
			ctl->accept_warned = 0;
		}
		/* max_connections is at most CTL_MAX_CLIENTS (role.c). */
		int room = (int)ctl->roles.max_connections - ctl->n_clients;
		if (room <= controller_reserve(ctl)) {
			struct ucred cred = { .pid = 0, .uid = (uid_t)-1, .gid = (gid_t)-1 };
			socklen_t len = sizeof(cred);
			getsockopt(fd, SOL_SOCKET, SO_PEERCRED, &cred, &len);
			if (room <= 0 || role_of_peer(&ctl->roles, fd, &cred) != ROLE_CONTROLLER) {
				refuse_connection(ctl, fd, &cred, room > 0);
				continue;
			}
		}
		ctl_client_add(ctl, fd);
	}
}

/* Roles and bounds ------------------------------------------------------ */

void ctl_set_roles(struct ctl *ctl, const struct role_settings *s)
{
	ctl->roles = *s;
	for (struct client *c = ctl->clients; c; c = c->next)
		c->role = role_of_peer(&ctl->roles, c->fd, &c->cred);
}

int ctl_need_role(struct client *c, enum role need, char *msg, size_t msg_size)
{
	const char *list = c->ctl->roles.controllers;

	if (c->role >= need)
		return 0;
	return CTL_ACK(SKY_ACK_PERMISSION, "%s role needed: uid %d reads only (controllers = %s)",
		       role_name(need), (int)c->cred.uid, list[0] ? list : "none");
}

unsigned ctl_uid_subscriptions(struct ctl *ctl, uid_t uid)
{
	unsigned n = 0;

	for (struct client *k = ctl->clients; k; k = k->next)
		n += k->cred.uid == uid && (k->sub_tables || k->sub_events);
	return n;
}

unsigned ctl_uid_views(struct ctl *ctl, uid_t uid)
{
	const struct sky_state *s = srv_state(ctl->srv);
	unsigned n = 0;

	for (struct client *k = ctl->clients; k; k = k->next)
		if (k->cred.uid == uid)
			for (uint32_t i = 0; i < s->n_views; i++)
				n += s->views[i].owner == k->id;
	return n;
}

/* Socket ---------------------------------------------------------------- */

int ctl_default_path(char *buf, size_t size)
{
	const char *xdg = getenv("XDG_RUNTIME_DIR");
	int n = xdg && *xdg ? snprintf(buf, size, "%s/skyd/control", xdg)
			    : snprintf(buf, size, "/run/skyd/control");

	return n < 0 || (size_t)n >= size ? -ENAMETOOLONG : 0;
}

#define SET_ERR(...) (snprintf(err, err_size, __VA_ARGS__))

/* The directory of the socket: made 0700 if missing; if present, a real
 * directory (no symlink), ours, and writable by nobody else, so that no
 * one can swap the socket under us. */
static int check_dir(const char *path, char *err, size_t err_size)
{
	char dir[sizeof(((struct sockaddr_un *)0)->sun_path)];
	struct stat st;
	char *slash;

	snprintf(dir, sizeof(dir), "%s", path);
	slash = strrchr(dir, '/');
	if (!slash)
		snprintf(dir, sizeof(dir), ".");
	else if (slash == dir)
		slash[1] = 0;
	else
		*slash = 0;
	if (mkdir(dir, 0700) < 0 && errno != EEXIST) {
		int e = errno;
		SET_ERR("cannot create '%s': %s (create its parent or pass --socket)", dir, strerror(e));
		return -e;
	}
	if (lstat(dir, &st) < 0) {
		int e = errno;
		SET_ERR("'%s': %s", dir, strerror(e));
		return -e;
	}
	if (!S_ISDIR(st.st_mode)) {
		SET_ERR("'%s' is not a directory", dir);
		return -ENOTDIR;
	}
	if (st.st_uid != geteuid()) {
		SET_ERR("'%s' belongs to uid %d, not to us (uid %d); remove it or pass --socket",
			dir, (int)st.st_uid, (int)geteuid());
		return -EPERM;
	}
	if (st.st_mode & 022) {
		/* Not "chmod go-w": the directory is usually shared on purpose
		 * (/tmp); a directory of our own is the fix. */
		const char *base = strrchr(path, '/');
		SET_ERR("'%s' is writable by others (mode %04o): any local user can put a socket of their own at that name and clients would talk to it; give the socket a directory of its own, e.g. --socket %s%sskyd-%d/%s (skyd creates it, mode 0700), or leave --socket out ($XDG_RUNTIME_DIR/skyd/control)",
			dir, (unsigned)(st.st_mode & 07777), dir, dir[strlen(dir) - 1] == '/' ? "" : "/",
			(int)geteuid(), base ? base + 1 : path);
		return -EPERM;
	}
	return 0;
}

static int make_socket(struct ctl *ctl, char *err, size_t err_size)
{
	struct sockaddr_un sa = { .sun_family = AF_UNIX };
	int fd, r;

	if (strlen(ctl->path) >= sizeof(sa.sun_path)) {
		SET_ERR("socket path '%s' is too long", ctl->path);
		return -ENAMETOOLONG;
	}
	r = check_dir(ctl->path, err, err_size);
	if (r < 0)
		return r;
	memcpy(sa.sun_path, ctl->path, strlen(ctl->path) + 1);
	fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
	if (fd < 0)
		return -errno;
	/* A socket that answers belongs to a live skyd; one that refuses is stale. */
	int probe = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
	if (probe >= 0) {
		if (connect(probe, (struct sockaddr *)&sa, sizeof(sa)) == 0) {
			close(probe);
			close(fd);
			SET_ERR("'%s': another skyd is listening there", ctl->path);
			return -EADDRINUSE;
		}
		close(probe);
	}
	unlink(ctl->path);
	mode_t old = umask(077);
	r = bind(fd, (struct sockaddr *)&sa, sizeof(sa));
	umask(old);
	if (r < 0 || listen(fd, 128) < 0) {
		r = -errno;
		close(fd);
		SET_ERR("'%s': %s", ctl->path, strerror(-r));
		return r;
	}
	ctl->created_socket = 1;
	ctl->listen_fd = fd;
	return 0;
}

int ctl_new(struct loop *l, struct srv *s, const char *path, int listen_fd, char *err,
	    size_t err_size, struct ctl **ret)
{
	struct ctl *ctl = calloc(1, sizeof(*ctl));
	int r;

	if (!ctl)
		return -ENOMEM;
	ctl->loop = l;
	ctl->srv = s;
	ctl->listen_fd = -1;
	role_settings_default(&ctl->roles);
	snprintf(ctl->path, sizeof(ctl->path), "%s", path);
	if (listen_fd >= 0) {
		ctl->listen_fd = listen_fd;
		fcntl(listen_fd, F_SETFL, fcntl(listen_fd, F_GETFL) | O_NONBLOCK);
	} else {
		r = make_socket(ctl, err, err_size);
		if (r < 0)
			goto fail;
	}
	r = loop_timer_add(l, accept_resume, ctl, &ctl->accept_timer);
	if (r < 0)
		goto fail;
	r = loop_io_add(l, ctl->listen_fd, EPOLLIN, accept_ready, ctl, &ctl->listen_io);
	if (r < 0)
		goto fail;
	r = srv_add_listener(s, &(struct srv_listener){ .published = on_published,
			     .failed = on_failed, .ctx = ctl });
	if (r < 0)
		goto fail;
	*ret = ctl;
	return 0;
fail:
	if (!err[0])
		SET_ERR("control socket: %s", strerror(-r));
	ctl_free(ctl);
	return r;
}

void ctl_set_sync(struct ctl *ctl, const struct ctl_sync *sync)
{
	if (sync)
		ctl->sync = *sync;
	else
		memset(&ctl->sync, 0, sizeof(ctl->sync));
}

int ctl_keep_socket(struct ctl *ctl)
{
	ctl->created_socket = 0;
	return ctl->listen_fd;
}

void ctl_free(struct ctl *ctl)
{
	if (!ctl)
		return;
	ctl->finishing = 1;	/* no demand or view changes on the way out */
	srv_remove_listener(ctl->srv, ctl);
	while (ctl->clients)
		ctl_client_drop(ctl->clients, NULL);
	loop_io_del(ctl->listen_io);
	loop_timer_del(ctl->accept_timer);
	if (ctl->listen_fd >= 0)
		close(ctl->listen_fd);
	if (ctl->created_socket)
		unlink(ctl->path);
	free(ctl);
}

int ctl_clients(const struct ctl *ctl)
{
	return ctl->n_clients;
}
