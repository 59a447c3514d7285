/* cmd_weather.c - the weather verbs: get weather and get clouds (reached
 * through get) and the metar key of set and batch, whose reply says what
 * the report gave. */
#include "ctl_internal.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "metar.h"
#include "srv.h"

static void emit_pair(void *ctx, const char *key, const char *value)
{
	ctl_reply_add(ctx, "%s: %s\n", key, value);
}

int ctl_get_weather(struct client *c, const struct proto_request *req, struct reply *r,
		    char *msg, size_t msg_size)
{
	char err[256] = "";

	if (req->n_args > 1)
		return CTL_ACK(SKY_ACK_SYNTAX, "get weather takes no other arguments");
	if (state_describe_weather(srv_state(c->ctl->srv), emit_pair, r, err, sizeof(err)) < 0)
		return CTL_ACK(SKY_ACK_RANGE, "%s", err);
	return 0;
}

int ctl_get_clouds(struct client *c, const struct proto_request *req, struct reply *r,
		   char *msg, size_t msg_size)
{
	if (req->n_args > 1)
		return CTL_ACK(SKY_ACK_SYNTAX, "get clouds takes no other arguments");
	state_describe_clouds(srv_state(c->ctl->srv), emit_pair, r);
	return 0;
}

/* Appends key=value of s to the note's applied list. */
static void note_key(struct ctl_metar *note, size_t *o, const struct sky_state *s, const char *key)
{
	char value[64];

	if (*o >= sizeof(note->applied) || state_get(s, key, value, sizeof(value)) < 0)
		return;
	*o += (size_t)snprintf(note->applied + *o, sizeof(note->applied) - *o, "%s%s=%s",
			       *o ? " " : "", key, value);
}

/* Number field f (layer_fields' order, 0..2) of a layer. */
static const double *layer_number(const struct state_cloud_layer *l, int f)
{
	return f == 0 ? &l->oktas : f == 1 ? &l->base_m : &l->top_m;
}

/* Whether field f (layer_fields' order) of a layer differs between a and
 * b, NAN against NAN the same. */
static int layer_field_changed(const struct state_cloud_layer *a, const struct state_cloud_layer *b,
			       int f)
{
	return f == 3 ? a->type != b->type
		      : memcmp(layer_number(a, f), layer_number(b, f), sizeof(double)) != 0;
}

int ctl_apply_metar(struct sky_state *s, const char *report, uint32_t *dirty,
		    struct ctl_metar *note, char *err, size_t err_size)
{
	struct state_cloud_layer was[STATE_CLOUD_LAYERS];
	struct metar *m = &note->report;
	uint32_t d = 0;

	memcpy(was, s->clouds.layer, sizeof(was));
	int r = state_set_metar(s, report, m, &d, err, err_size);

	if (r < 0)
		return r;
	/* What the report sets, in this order; the site's pressure and
	 * temperature only when it had them; the layers it has (a top only
	 * where it cleared one), and every key of the others it cleared; the
	 * wind when it has one. */
	const enum state_key_id applied[] = {
		STATE_KEY_ID_VISIBILITY_KM, STATE_KEY_ID_RELATIVE_HUMIDITY, STATE_KEY_ID_AEROSOL,
		STATE_KEY_ID_CLOUD_OKTAS,
		isfinite(m->qnh_hpa) ? STATE_KEY_ID_PRESSURE_MBAR : STATE_KEY_ID_NONE,
		isfinite(m->temperature_c) ? STATE_KEY_ID_TEMPERATURE_C : STATE_KEY_ID_NONE,
	};
	static const char *const layer_fields[] = { "oktas", "base_m", "top_m", "type" };
	size_t o = 0;
	char key[32];
	double dir_deg, speed_mps;

	*dirty |= d;
	note->given = 1;
	note->applied[0] = 0;
	for (size_t i = 0; i < sizeof(applied) / sizeof(applied[0]); i++)
		if (applied[i])
			note_key(note, &o, s, state_key_name(applied[i]));
	for (int i = 0; i < STATE_CLOUD_LAYERS; i++) {
		int filled = !isnan(s->clouds.layer[i].oktas);
		for (int f = 0; f < 4; f++) {
			if (!layer_field_changed(&was[i], &s->clouds.layer[i], f) && (!filled || f == 2))
				continue;
			snprintf(key, sizeof(key), "cloud%d_%s", i + 1, layer_fields[f]);
			note_key(note, &o, s, key);
		}
	}
	if (metar_wind(m, &dir_deg, &speed_mps) == 0) {
		if (!isnan(dir_deg))
			note_key(note, &o, s, "wind_dir_deg");
		note_key(note, &o, s, "wind_speed_mps");
	}
	return 0;
}

void ctl_reply_metar(struct reply *r, const struct ctl_metar *note)
{
	if (!note->given)
		return;
	ctl_reply_add(r, "metar_used: %s\nmetar_ignored: %s\nmetar_applied: %s\n",
		      note->report.used[0] ? note->report.used : "none",
		      note->report.ignored[0] ? note->report.ignored : "none", note->applied);
}
