/* cmd_tables.c - the verbs about the published tables: status,
 * subscribe (the shared memory and events), unsubscribe, and sample
 * (reading the current slot as a client would). */
#include "ctl_internal.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pub.h"
#include "skymap.h"
#include "skysample.h"
#include "srv.h"

int ctl_cmd_status(struct client *c, const struct proto_request *req, struct reply *r,
		   char *msg, size_t msg_size)
{
	struct srv *s = c->ctl->srv;
	const struct eng_device *d = srv_device(s);
	struct srv_status st;
	char names[64];
	int subscribers = 0, controllers = 0;

	srv_status(s, &st);
	for (struct client *k = c->ctl->clients; k; k = k->next) {
		subscribers += k->sub_tables || k->sub_events;
		controllers += k->role == ROLE_CONTROLLER;
	}
	ctl_reply_add(r, "generation: %llu\n", (unsigned long long)st.generation);
	ctl_reply_add(r, "computing: %d\npending: %d\n", st.computing, st.pending);
	state_format_all_tables(st.last_computed, names, sizeof(names));
	ctl_reply_add(r, "tables_computed: %s\n", names);
	state_format_tables(st.published_valid, names, sizeof(names));
	ctl_reply_add(r, "tables_valid: %s\n", names);
	state_format_all_tables(st.published_computed, names, sizeof(names));
	ctl_reply_add(r, "last_computed: %s\n", names);
	state_format_tables(st.demand, names, sizeof(names));
	ctl_reply_add(r, "demand: %s\n", names);
	state_format_tables(st.needed, names, sizeof(names));
	ctl_reply_add(r, "tables_needed: %s\n", names);
	const struct sky_shm_slot *cur = pub_current(srv_pub(s), NULL);
	ctl_reply_add(r, "views: %u\n", srv_state(s)->n_views);
	for (uint32_t i = 0; i < cur->n_views && i < SKY_SHM_MAX_VIEWS; i++)
		ctl_reply_add(r, "view: name=%.*s index=%u valid=%d\n", (int)SKY_SHM_VIEW_NAME_MAX,
			  cur->views[i].name, i, !!(cur->valid_views & (1u << i)));
	ctl_reply_add(r, "compute_ms: %.3f\n", st.last_total_ms);
	for (int t = 0; t < STATE_N_TABLES; t++)
		ctl_reply_add(r, "%s_ms: %.3f\n", state_table_names[t], st.table_ms[t]);
	ctl_reply_add(r, "computations: %llu\nfailures: %llu\n", (unsigned long long)st.computations,
		  (unsigned long long)st.failures);
	ctl_reply_add(r, "column_passes: %llu\n", (unsigned long long)st.column_passes);
	ctl_reply_add(r, "clouds_made_ahead: %llu\nclouds_taken_ahead: %llu\n",
		      (unsigned long long)st.clouds_made_ahead, (unsigned long long)st.clouds_taken_ahead);
	ctl_reply_add(r, "last_error: %s\n", st.last_error[0] ? st.last_error : "none");
	ctl_reply_add(r, "storage_warning: %s\n", st.storage_warning[0] ? st.storage_warning : "none");
	ctl_reply_add(r, "device: %s\ndevice_type: %s\n", d->name, d->type_name);
	ctl_reply_add(r, "grain: %s\npublish: %s\n", eng_grain_name(srv_grain(s)),
		      st.publish_direct ? "direct" : "copy");
	ctl_reply_add(r, "clients: %d\nsubscribers: %d\n", c->ctl->n_clients, subscribers);
	ctl_reply_add(r, "role: %s\ncontroller_clients: %d\nmax_connections: %u\n",
		      role_name(c->role), controllers, c->ctl->roles.max_connections);
	ctl_reply_add(r, "shm_bytes: %llu\n", (unsigned long long)pub_bytes(srv_pub(s)));
	ctl_reply_add(r, "protocol: %s\n", SKY_PROTO_VERSION);
	ctl_reply_add(r, "clock_ticks: %llu\nclock_changes: %llu\n",
		      (unsigned long long)st.clock_ticks, (unsigned long long)st.clock_changes);
	if (st.clock_next_tick_s < 0)
		ctl_reply_add(r, "clock_next_tick_s: none\n");
	else
		ctl_reply_add(r, "clock_next_tick_s: %.3f\n", st.clock_next_tick_s);
	ctl_status_sensor(c->ctl, r);
	if (c->ctl->sync.status) {
		char sync[1024] = "";
		c->ctl->sync.status(c->ctl->sync.ctx, sync, sizeof(sync));
		ctl_reply_add(r, "%s", sync);
	} else {
		ctl_reply_add(r, "sync: off\n");
	}
	return 0;
}

static const char *format_name(uint32_t f)
{
	return f == SKY_FORMAT_RGBA16F ? "rgba16f" : "rgba32f";
}

int ctl_cmd_subscribe(struct client *c, const struct proto_request *req, struct reply *r,
		      char *msg, size_t msg_size)
{
	uint32_t tables = 0;
	int events = -1, fd = -1;

	for (int i = 0; i < req->n_args; i++) {
		const struct proto_arg *a = &req->args[i];
		if (!a->value)
			return CTL_ACK(SKY_ACK_SYNTAX, "'%s': key=value expected", a->key);
		if (strcmp(a->key, "tables") == 0) {
			if (state_parse_tables(a->value, &tables) < 0)
				return CTL_ACK(SKY_ACK_NO_EXIST, "tables: '%s' is not a list of transmittance, multiscatter, skyview, aerial, cloud, shadow or all", a->value);
		} else if (strcmp(a->key, "events") == 0) {
			if (strcmp(a->value, "0") && strcmp(a->value, "1"))
				return CTL_ACK(SKY_ACK_ARG, "events: '%s' is not 0 or 1", a->value);
			events = a->value[0] == '1';
		} else {
			return CTL_ACK(SKY_ACK_NO_EXIST, "%s: unknown key (tables, events)", a->key);
		}
	}
	int held = c->sub_tables || c->sub_events;
	int holds = tables || (events >= 0 ? events : c->sub_events) || c->sub_tables;
	unsigned mine = ctl_uid_subscriptions(c->ctl, c->cred.uid);
	if (!held && holds && mine >= c->ctl->roles.max_subscriptions_per_uid)
		return CTL_ACK(SKY_ACK_LIMIT, "uid %d holds %u subscriptions (max_subscriptions_per_uid = %u); unsubscribe or close one",
			   (int)c->cred.uid, mine, c->ctl->roles.max_subscriptions_per_uid);
	if (tables) {
		/* Taken before anything changes, so that a refusal changes nothing. */
		fd = fcntl(pub_fd(srv_pub(c->ctl->srv)), F_DUPFD_CLOEXEC, 3);
		if (fd < 0)
			return CTL_ACK(SKY_ACK_LIMIT, "no file descriptor free to pass the shared memory (%s); try again",
				   strerror(errno));
	}
	if (events >= 0)
		c->sub_events = events;
	if (!tables) {
		ctl_reply_add(r, "events: %d\n", c->sub_events);
		return 0;
	}
	c->sub_tables = tables;
	ctl_update_demand(c->ctl);
	struct pub *p = srv_pub(c->ctl->srv);
	const struct sky_shm_header *h = pub_header(p);
	ctl_reply_add(r, "generation: %llu\n", (unsigned long long)h->generation);
	ctl_reply_add(r, "events: %d\n", c->sub_events);
	ctl_reply_add(r, "shm_bytes: %llu\nheader_bytes: %u\nslots: %u\nslot_bytes: %llu\n",
		  (unsigned long long)h->total_bytes, h->header_bytes, h->n_slots,
		  (unsigned long long)h->slot_bytes);
	ctl_reply_add(r, "layout_version: %u\nuv_mapping_version: %u\n", h->layout_version,
		  h->uv_mapping_version);
	for (uint32_t t = 0; t < h->n_tables; t++) {
		const struct sky_shm_table *d = &h->tables[t];
		ctl_reply_add(r, "table: name=%s format=%s width=%u height=%u depth=%u texel_bytes=%u offset=%llu bytes=%llu\n",
			  proto_table_name(d->id), format_name(d->format), d->width, d->height, d->depth,
			  d->texel_bytes, (unsigned long long)d->offset,
			  (unsigned long long)d->bytes);
	}
	r->fd = fd;
	return 0;
}

int ctl_cmd_unsubscribe(struct client *c, const struct proto_request *req, struct reply *r,
			char *msg, size_t msg_size)
{
	c->sub_tables = 0;
	c->sub_events = 0;
	c->sample_tables = 0;
	ctl_update_demand(c->ctl);
	return 0;
}

static void reply_rgb(struct reply *r, const char *key_rgb, const char *key_y, const double rgb[3])
{
	/* Rec. 709 / sRGB primaries: the luminance of linear RGB. */
	double y = 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];

	ctl_reply_add(r, "%s: %.9g,%.9g,%.9g\n%s: %.9g\n", key_rgb, rgb[0], rgb[1], rgb[2], key_y, y);
}

/* The table a sample reads is not in the current slot: the connection now
 * demands it and the request (and the connection's input after it) waits
 * for the generation that brings it (proto/PROTOCOL.md, "Demand"). */
static int sample_wait(struct client *c, uint32_t id, char *msg, size_t msg_size)
{
	ctl_update_demand(c->ctl);
	if (!(srv_tables_coming(c->ctl->srv) & (1u << id)))
		return CTL_ACK(SKY_ACK_STATE, "no %s table published yet", state_table_names[id]);
	c->deferred = strdup(c->line);
	if (!c->deferred)
		return CTL_ACK(SKY_ACK_LIMIT, "out of memory");
	return -1;
}

/* Samples the current slot exactly as a client would (skysample.h). The
 * daemon is its only writer and runs on this thread, so no seqlock retry. */
int ctl_cmd_sample(struct client *c, const struct proto_request *req, struct reply *r,
		   char *msg, size_t msg_size)
{
	const struct pub *p = srv_pub(c->ctl->srv);
	const struct sky_shm_header *h = pub_header(p);
	const uint8_t *base;
	const struct sky_shm_slot *slot = pub_current(p, &base);
	const char *what = req->args[0].key;
	struct skysample_table t;
	double rgb[3];
	uint32_t id;

	if (req->args[0].value)
		return CTL_ACK(SKY_ACK_SYNTAX, "usage: sample sky el_deg=E az_deg=A | sample sun | sample ambient");
	if (strcmp(what, "sky") == 0 || strcmp(what, "ambient") == 0)
		id = SKY_TABLE_SKYVIEW;
	else if (strcmp(what, "sun") == 0)
		id = SKY_TABLE_TRANSMITTANCE;
	else
		return CTL_ACK(SKY_ACK_NO_EXIST, "%s: not sky, sun or ambient", what);
	if (strcmp(what, "sky") == 0) {
		double el, az;
		const char *ev = proto_arg_value(req->args, req->n_args, "el_deg");
		const char *av = proto_arg_value(req->args, req->n_args, "az_deg");
		for (int i = 1; i < req->n_args; i++)
			if (strcmp(req->args[i].key, "el_deg") && strcmp(req->args[i].key, "az_deg"))
				return CTL_ACK(SKY_ACK_NO_EXIST, "%s: unknown key (el_deg, az_deg)", req->args[i].key);
		if (!ev || !av)
			return CTL_ACK(SKY_ACK_SYNTAX, "usage: sample sky el_deg=E az_deg=A");
		if (proto_parse_number(ev, &el) < 0)
			return CTL_ACK(SKY_ACK_ARG, "el_deg: '%s' is not a finite number", ev);
		if (proto_parse_number(av, &az) < 0)
			return CTL_ACK(SKY_ACK_ARG, "az_deg: '%s' is not a finite number", av);
		if (el < -90 || el > 90)
			return CTL_ACK(SKY_ACK_RANGE, "el_deg: %g is outside [-90, 90]", el);
		if (az < -360 || az > 720)
			return CTL_ACK(SKY_ACK_RANGE, "az_deg: %g is outside [-360, 720]", az);
		c->sample_tables |= 1u << id;
		if (!(slot->valid_tables & (1u << id)))
			return sample_wait(c, id, msg, msg_size);
		if (skysample_table_from_slot(h, base, id, &t) < 0)
			return CTL_ACK(SKY_ACK_STATE, "no sky-view table published yet");
		skysample_sky(&t, &slot->state, el * SKYMAP_PI / 180.0, az * SKYMAP_PI / 180.0, rgb);
		ctl_reply_add(r, "generation: %llu\n", (unsigned long long)slot->generation);
		reply_rgb(r, "radiance_rgb_cd_m2", "luminance_cd_m2", rgb);
		return 0;
	}
	if (req->n_args > 1)
		return CTL_ACK(SKY_ACK_SYNTAX, "sample %s takes no arguments", what);
	c->sample_tables |= 1u << id;
	if (!(slot->valid_tables & (1u << id)))
		return sample_wait(c, id, msg, msg_size);
	if (skysample_table_from_slot(h, base, id, &t) < 0)
		return CTL_ACK(SKY_ACK_STATE, "no %s table published yet", state_table_names[id]);
	if (id == SKY_TABLE_TRANSMITTANCE)
		skysample_sun(&t, &slot->state, rgb);
	else
		skysample_ambient(&t, &slot->state, rgb);
	ctl_reply_add(r, "generation: %llu\n", (unsigned long long)slot->generation);
	reply_rgb(r, "illuminance_rgb_lx", "illuminance_lx", rgb);
	return 0;
}

