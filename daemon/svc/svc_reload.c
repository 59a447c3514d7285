/* svc_reload.c - SIGHUP: the config file re-read whole, checked by every
 * settings group, then applied together or not at all. */
#include "svc_reload.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ctl.h"
#include "log.h"
#include "srv.h"
#include "state.h"
#include "svc_notify.h"

struct svc_reload {
	const char *path;
	char *const *args;
	int n_args;
	struct srv *srv;
	struct ctl *ctl;
	struct svc_notify *notify;
	struct svc_reload_step steps[SVC_RELOAD_MAX_STEPS];
	int n_steps;
};

int svc_reload_new(const char *path, char *const *args, int n_args, struct svc_reload **ret)
{
	struct svc_reload *r = calloc(1, sizeof(*r));

	if (!r)
		return -ENOMEM;
	r->path = path;
	r->args = args;
	r->n_args = n_args;
	*ret = r;
	return 0;
}

void svc_reload_attach(struct svc_reload *r, struct srv *srv, struct svc_notify *notify,
		       struct ctl *ctl)
{
	r->ctl = ctl;
	r->srv = srv;
	r->notify = notify;
}

void svc_reload_free(struct svc_reload *r)
{
	free(r);
}

int svc_reload_add_step(struct svc_reload *r, const struct svc_reload_step *step)
{
	if (r->n_steps >= SVC_RELOAD_MAX_STEPS)
		return -ENOSPC;
	r->steps[r->n_steps++] = *step;
	return 0;
}

/* config_key_fn over every step: the first that knows the key takes it. */
static int steps_key(void *ctx, const char *key, const char *value, char *err, size_t err_size)
{
	struct svc_reload *r = ctx;

	for (int i = 0; i < r->n_steps; i++) {
		int k = r->steps[i].key(r->steps[i].ctx, key, value, err, err_size);
		if (k != 0)
			return k;
	}
	return 0;
}

/* Parses and checks everything into next and the steps' candidates;
 * nothing is applied. */
static int prepare(struct svc_reload *r, struct sky_state *next, char *err, size_t err_size)
{
	char msg[384];
	int e;

	for (int i = 0; i < r->n_steps; i++)
		if (r->steps[i].begin)
			r->steps[i].begin(r->steps[i].ctx);
	if (r->path) {
		e = config_load_with(r->path, next, steps_key, r, err, err_size);
		if (e < 0)
			return e;
	}
	for (int i = 0; i < r->n_args; i++)
		if (state_set_pair(next, r->args[i], NULL, msg, sizeof(msg)) < 0) {
			snprintf(err, err_size, "argument %s: %s", r->args[i], msg);
			return -EINVAL;
		}
	if (state_validate(next, 0, msg, sizeof(msg)) < 0) {
		snprintf(err, err_size, "%s", msg);
		return -EINVAL;
	}
	for (int i = 0; i < r->n_steps; i++) {
		if (!r->steps[i].check)
			continue;
		msg[0] = 0;
		e = r->steps[i].check(r->steps[i].ctx, msg, sizeof(msg));
		if (e < 0) {
			snprintf(err, err_size, "%s: %s: %s", r->path ? r->path : "arguments",
				 r->steps[i].name,
				 msg[0] ? msg : strerror(-e));
			return e;
		}
	}
	return 0;
}

/* Makes every step's checked candidate current. */
static void apply_steps(struct svc_reload *r)
{
	for (int i = 0; i < r->n_steps; i++)
		if (r->steps[i].apply)
			r->steps[i].apply(r->steps[i].ctx);
}

int svc_reload_load(struct svc_reload *r, struct sky_state *s, char *err, size_t err_size)
{
	struct sky_state next = *s;
	int e = prepare(r, &next, err, err_size);

	if (e < 0)
		return e;
	apply_steps(r);
	*s = next;
	return 0;
}

int svc_reload_run(struct svc_reload *r, char *err, size_t err_size)
{
	struct sky_state next;
	uint64_t generation = 0;
	uint32_t dirty;
	char msg[384] = "";
	int e;

	if (!r->path || !r->srv) {
		snprintf(err, err_size, "%s", r->path ? "not serving yet" : "no --config file to reload");
		log_warning("reload: %s", err);
		return -ENOENT;
	}
	if (r->notify)
		svc_notify_reloading(r->notify);
	next = *srv_state(r->srv);
	e = prepare(r, &next, err, err_size);
	char who[128] = "";
	if (e == 0 && r->ctl && ctl_sky_follows(r->ctl, who, sizeof(who))) {
		/* A follower's sky is the controller's: the file's keys would
		 * part it from the others until the next replicated change. */
		log_info("reload: the sky's keys are not applied: this skyd follows controller %s",
			 who);
	} else if (e == 0) {
		/* The sky last: srv_apply is the one step that can still refuse
		 * (device limits, lights astro cannot place), and it changes
		 * nothing when it does; only the tables the changed keys
		 * invalidate are recomputed. */
		dirty = state_diff(srv_state(r->srv), &next);
		e = srv_apply(r->srv, &next, dirty, &generation, &dirty, msg, sizeof(msg));
		if (e < 0)
			snprintf(err, err_size, "%s: %s", r->path, msg[0] ? msg : strerror(-e));
	}
	if (e == 0) {
		apply_steps(r);
		log_info("reload: %s applied, generation %llu", r->path,
			 (unsigned long long)generation);
	} else {
		log_error("reload refused, nothing changed: %s", err);
	}
	if (r->notify)
		svc_notify_reloaded(r->notify);
	return e;
}
