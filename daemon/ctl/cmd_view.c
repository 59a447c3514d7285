/* cmd_view.c - the view verb: cameras with their own aerial-perspective
 * volume, owned by the connection that added them. */
#include "ctl_internal.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "log.h"
#include "srv.h"

static int view_find(const struct sky_state *s, const char *name)
{
	for (uint32_t i = 0; i < s->n_views; i++)
		if (strcmp(s->views[i].name, name) == 0)
			return (int)i;
	return -1;
}

static void view_remove(struct sky_state *s, uint32_t i)
{
	memmove(&s->views[i], &s->views[i + 1], (s->n_views - i - 1) * sizeof(s->views[0]));
	s->n_views--;
	memset(&s->views[s->n_views], 0, sizeof(s->views[0]));
}

/* Views belong to the connection that added them and go with it: a view
 * nobody uses any more is dropped. */
void ctl_views_drop_owner(struct ctl *ctl, uint64_t owner)
{
	struct sky_state next = *srv_state(ctl->srv);
	char err[256];
	uint64_t generation;
	uint32_t dirty = STATE_BIT(STATE_AERIAL);
	int changed = 0;

	for (uint32_t i = next.n_views; i-- > 0;)
		if (next.views[i].owner == owner) {
			view_remove(&next, i);
			changed = 1;
		}
	if (changed && srv_apply(ctl->srv, &next, dirty, &generation, &dirty, err, sizeof(err)) < 0)
		log_error("dropping the views of client %llu: %s", (unsigned long long)owner, err);
}

static const char *const view_form_names[] = {
	[SKY_VIEW_VOLUME] = "volume",
	[SKY_VIEW_PANORAMA] = "panorama",
};

static int view_form(const char *name)
{
	for (size_t i = 0; i < sizeof(view_form_names) / sizeof(view_form_names[0]); i++)
		if (strcmp(view_form_names[i], name) == 0)
			return (int)i;
	return -EINVAL;
}

/* A view's camera and place; its altitude is the state's key altitude_km,
 * per view (view_altitude). */
static const struct {
	const char *key;
	size_t offset;			/* in struct state_view */
	double min, max;
} view_keys[] = {
	{ "east_km", offsetof(struct state_view, east_km), -1e4, 1e4 },
	{ "north_km", offsetof(struct state_view, north_km), -1e4, 1e4 },
	{ "yaw_deg", offsetof(struct state_view, camera.yaw_deg), -360, 720 },
	{ "pitch_deg", offsetof(struct state_view, camera.pitch_deg), -90, 90 },
	{ "roll_deg", offsetof(struct state_view, camera.roll_deg), -180, 180 },
	{ "vfov_deg", offsetof(struct state_view, camera.vfov_deg), 0.1, 179 },
	{ "aspect", offsetof(struct state_view, camera.aspect), 0.01, 100 },
};

/* The view's altitude, value for the row altitude_km: its parser and
 * range. 0, or the ACK code with msg. */
static int view_altitude(const char *value, struct state_view *v, char *msg, size_t msg_size)
{
	char err[256];
	int e = state_key_parse(state_key_of(STATE_KEY_ID_ALTITUDE_KM), value, &v->altitude_km, err,
				sizeof(err));

	if (e < 0)
		return CTL_ACK(e == -ERANGE ? SKY_ACK_RANGE : SKY_ACK_ARG, "%s", err);
	return 0;
}

static int view_add(struct client *c, const struct proto_request *req, struct reply *r,
		    char *msg, size_t msg_size)
{
	struct sky_state next = *srv_state(c->ctl->srv);
	struct state_view v = { .altitude_km = NAN, .owner = c->id };
	const char *name = proto_arg_value(req->args, req->n_args, "name");

	state_default_camera(&v.camera);
	if (!name)
		return CTL_ACK(SKY_ACK_SYNTAX, "usage: view add name=NAME [form=volume|panorama] [altitude_km=H] [east_km=] [north_km=] [yaw_deg=] [pitch_deg=] [roll_deg=] [vfov_deg=] [aspect=]");
	size_t n = strlen(name);
	if (n == 0 || n >= STATE_VIEW_NAME_MAX || strspn(name, "abcdefghijklmnopqrstuvwxyz"
		"ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-.") != n)
		return CTL_ACK(SKY_ACK_ARG, "name: '%s' is not 1 to %d letters, digits, '_', '-' or '.'",
			   name, STATE_VIEW_NAME_MAX - 1);
	snprintf(v.name, sizeof(v.name), "%s", name);
	for (int i = 1; i < req->n_args; i++) {
		const struct proto_arg *a = &req->args[i];
		size_t k;
		double d;
		if (!a->value)
			return CTL_ACK(SKY_ACK_SYNTAX, "'%s': key=value expected", a->key);
		if (strcmp(a->key, "name") == 0)
			continue;
		if (strcmp(a->key, "form") == 0) {
			int f = view_form(a->value);
			if (f < 0)
				return CTL_ACK(SKY_ACK_ARG, "form: '%s' is not volume or panorama", a->value);
			v.form = (uint32_t)f;
			continue;
		}
		if (strcmp(a->key, state_key_name(STATE_KEY_ID_ALTITUDE_KM)) == 0) {
			int code = view_altitude(a->value, &v, msg, msg_size);
			if (code)
				return code;
			continue;
		}
		for (k = 0; k < sizeof(view_keys) / sizeof(view_keys[0]); k++)
			if (strcmp(view_keys[k].key, a->key) == 0)
				break;
		if (k == sizeof(view_keys) / sizeof(view_keys[0]))
			return CTL_ACK(SKY_ACK_NO_EXIST, "%s: unknown key (name, form, altitude_km, east_km, north_km, yaw_deg, pitch_deg, roll_deg, vfov_deg, aspect)", a->key);
		if (proto_parse_number(a->value, &d) < 0)
			return CTL_ACK(SKY_ACK_ARG, "%s: '%s' is not a finite number", a->key, a->value);
		if (d < view_keys[k].min || d > view_keys[k].max)
			return CTL_ACK(SKY_ACK_RANGE, "%s: %g is outside [%g, %g]", a->key, d,
				   view_keys[k].min, view_keys[k].max);
		*(double *)((char *)&v + view_keys[k].offset) = d;
	}
	int i = view_find(&next, v.name);
	if (i >= 0 && next.views[i].owner != c->id)
		return CTL_ACK(SKY_ACK_ARG, "name: view '%s' belongs to another connection", v.name);
	if (i < 0 && next.n_views == STATE_MAX_VIEWS)
		return CTL_ACK(SKY_ACK_LIMIT, "%d views already (SKY_SHM_MAX_VIEWS)", STATE_MAX_VIEWS);
	unsigned mine = ctl_uid_views(c->ctl, c->cred.uid);
	if (i < 0 && mine >= c->ctl->roles.max_views_per_uid)
		return CTL_ACK(SKY_ACK_LIMIT, "uid %d holds %u views (max_views_per_uid = %u); delete one or close its connection",
			   (int)c->cred.uid, mine, c->ctl->roles.max_views_per_uid);
	if (i < 0)
		i = (int)next.n_views++;
	int same = memcmp(&next.views[i], &v, sizeof(v)) == 0;
	next.views[i] = v;
	return ctl_commit(c, &next, same ? 0 : STATE_BIT(STATE_AERIAL), r, msg, msg_size);
}

int ctl_cmd_view(struct client *c, const struct proto_request *req, struct reply *r,
		 char *msg, size_t msg_size)
{
	const char *what = req->args[0].key;
	const struct sky_state *s = srv_state(c->ctl->srv);

	if (req->args[0].value)
		return CTL_ACK(SKY_ACK_SYNTAX, "usage: view add|del|list ...");
	if ((strcmp(what, "add") == 0 || strcmp(what, "del") == 0) &&
	    ctl_need_role(c, ROLE_CONTROLLER, msg, msg_size))
		return SKY_ACK_PERMISSION;
	if (strcmp(what, "add") == 0)
		return view_add(c, req, r, msg, msg_size);
	if (strcmp(what, "del") == 0) {
		const char *name = proto_arg_value(req->args, req->n_args, "name");
		if (!name || req->n_args != 2)
			return CTL_ACK(SKY_ACK_SYNTAX, "usage: view del name=NAME");
		int i = view_find(s, name);
		if (i < 0)
			return CTL_ACK(SKY_ACK_NO_EXIST, "name: no view '%s'", name);
		struct sky_state next = *s;
		view_remove(&next, (uint32_t)i);
		return ctl_commit(c, &next, STATE_BIT(STATE_AERIAL), r, msg, msg_size);
	}
	if (strcmp(what, "list") == 0) {
		if (req->n_args != 1)
			return CTL_ACK(SKY_ACK_SYNTAX, "usage: view list");
		for (uint32_t i = 0; i < s->n_views; i++) {
			const struct state_view *v = &s->views[i];
			char alt[32];
			if (isnan(v->altitude_km))
				snprintf(alt, sizeof(alt), "observer");
			else
				snprintf(alt, sizeof(alt), "%.9g", v->altitude_km);
			ctl_reply_add(r, "view: name=%s index=%u altitude_km=%s yaw_deg=%.9g pitch_deg=%.9g roll_deg=%.9g vfov_deg=%.9g aspect=%.9g east_km=%.9g north_km=%.9g form=%s mine=%d\n",
				  v->name, i, alt, v->camera.yaw_deg, v->camera.pitch_deg,
				  v->camera.roll_deg, v->camera.vfov_deg, v->camera.aspect, v->east_km, v->north_km,
				  view_form_names[v->form], v->owner == c->id);
		}
		return 0;
	}
	return CTL_ACK(SKY_ACK_NO_EXIST, "%s: not add, del or list", what);
}

