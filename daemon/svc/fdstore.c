/* fdstore.c - skyd's fds in systemd's file-descriptor store and back. */
#include "fdstore.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <systemd/sd-daemon.h>
#include <unistd.h>

#include "log.h"
#include "pub.h"

#define FDSTORE_MAX_PASSED 16

struct fdstore {
	bool enabled;
	int shm_fd;			/* passed as shm, -1 none or taken */
	int control_fd;			/* passed as control, -1 none or taken */
	int activated[FDSTORE_MAX_PASSED];	/* the others, -1 once taken */
	int n_activated;
	bool shm_passed;		/* the store held a region at start */
	bool shm_adopted;		/* ... and it is the one we publish into */
	bool control_passed;
	bool control_adopted;		/* the passed control socket is ours again */
};

/* $FDSTORE as systemd sets it: the store's size, 0 when there is none. */
static bool store_enabled(void)
{
	const char *n = getenv("NOTIFY_SOCKET"), *m = getenv("FDSTORE");
	char *end;

	if (!n || !*n || !m)
		return false;
	long v = strtol(m, &end, 10);
	return end != m && !*end && v > 0;
}

int fdstore_new(struct fdstore **ret)
{
	struct fdstore *f = calloc(1, sizeof(*f));
	char **names = NULL;

	if (!f)
		return -ENOMEM;
	f->enabled = store_enabled();
	f->shm_fd = f->control_fd = -1;
	int n = sd_listen_fds_with_names(1, &names);
	for (int i = 0; i < n; i++) {
		int fd = SD_LISTEN_FDS_START + i;
		const char *name = names && names[i] ? names[i] : "unknown";
		if (strcmp(name, "shm") == 0 && f->shm_fd < 0) {
			f->shm_fd = fd;
			f->shm_passed = true;
		} else if (strcmp(name, "control") == 0 && f->control_fd < 0) {
			f->control_fd = fd;
			f->control_passed = true;
		} else if (strcmp(name, "shm") != 0 && strcmp(name, "control") != 0 &&
			   f->n_activated < FDSTORE_MAX_PASSED) {
			f->activated[f->n_activated++] = fd;
		} else {
			close(fd);
		}
	}
	for (int i = 0; names && i < n; i++)
		free(names[i]);
	free(names);
	*ret = f;
	return 0;
}

void fdstore_free(struct fdstore *f)
{
	if (!f)
		return;
	if (f->shm_fd >= 0)
		close(f->shm_fd);
	if (f->control_fd >= 0)
		close(f->control_fd);
	for (int i = 0; i < f->n_activated; i++)
		if (f->activated[i] >= 0)
			close(f->activated[i]);
	free(f);
}

bool fdstore_enabled(const struct fdstore *f)
{
	return f->enabled;
}

int fdstore_region(struct fdstore *f, const struct sky_state *s, struct pub **ret_pub,
		   uint64_t *ret_generation)
{
	uint64_t generation = 0;
	int r;

	*ret_pub = NULL;
	*ret_generation = 0;
	if (f->shm_fd >= 0) {
		r = pub_adopt(f->shm_fd, s, ret_pub, &generation);
		if (r == 0) {
			f->shm_fd = -1;
			f->shm_adopted = true;
			*ret_generation = generation;
			log_info("shared memory: adopted the stored region at generation %llu; clients keep their mapping",
				 (unsigned long long)generation);
			return 0;
		}
		if (r == -ESTALE)
			log_info("shared memory: the stored region has another layout; a new one from generation %llu, clients remap",
				 (unsigned long long)generation + 1);
		else
			log_warning("shared memory: the stored region cannot be adopted (%s); a new one, clients remap",
				    strerror(-r));
		close(f->shm_fd);
		f->shm_fd = -1;
	}
	if (!f->enabled)
		return 0;
	r = pub_new_adoptable(s, generation, ret_pub);
	if (r < 0)
		return r;
	*ret_generation = generation;
	return 0;
}

int fdstore_control(struct fdstore *f, const char *path)
{
	int fd = f->control_fd;

	if (fd < 0)
		return -1;
	f->control_fd = -1;
	if (sd_is_socket_unix(fd, SOCK_STREAM, 1, path, 0) > 0) {
		f->control_adopted = true;
		log_info("control socket: the stored one, still listening on %s", path);
		return fd;
	}
	close(fd);
	return -1;
}

int fdstore_activated(struct fdstore *f)
{
	for (int i = 0; i < f->n_activated; i++) {
		int fd = f->activated[i];
		if (fd >= 0) {
			f->activated[i] = -1;
			return fd;
		}
	}
	return -1;
}

/* Stores fd under name; replacing: first drops what the store holds under
 * that name. */
static int store(const char *name, int fd, bool replacing)
{
	char msg[96];
	int r;

	if (replacing) {
		snprintf(msg, sizeof(msg), "FDSTOREREMOVE=1\nFDNAME=%s", name);
		r = sd_notify(0, msg);
		if (r < 0)
			return r;
	}
	snprintf(msg, sizeof(msg), "FDSTORE=1\nFDNAME=%s", name);
	r = sd_pid_notify_with_fds(0, 0, msg, &fd, 1);
	return r < 0 ? r : r == 0 ? -ENOTCONN : 0;
}

int fdstore_hand_over(struct fdstore *f, const struct pub *p, int listen_fd)
{
	int fd = pub_store_fd(p), r;

	if (!f->enabled)
		return 0;
	if (fd < 0) {
		log_warning("fd store: the shared memory is sealed against writes; not stored");
		return fd;
	}
	/* The region first: without the socket a restart still keeps mappings. */
	r = store("shm", fd, f->shm_passed && !f->shm_adopted);
	if (r == 0 && listen_fd >= 0)
		r = store("control", listen_fd, f->control_passed && !f->control_adopted);
	if (r < 0) {
		log_warning("fd store: %s; a restart will lose the clients' mappings", strerror(-r));
		return r;
	}
	f->shm_passed = true;
	f->shm_adopted = true;
	log_info("fd store: shared memory%s handed to systemd", listen_fd >= 0 ? " and control socket" : "");
	return 0;
}

void fdstore_replaced(struct fdstore *f, const struct pub *p)
{
	int fd = pub_store_fd(p);

	if (!f->enabled || fd < 0)
		return;
	int r = store("shm", fd, true);
	if (r < 0)
		log_warning("fd store: the new region: %s", strerror(-r));
}
