/* cmd_weather.c - the weather verbs: get weather (reached through get) and
 * the metar key of set and batch, whose reply says what the report gave. */
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

int ctl_apply_metar(struct sky_state *s, const char *report, uint32_t *dirty,
		    struct ctl_metar *note, char *err, size_t err_size)
{
	struct metar *m = &note->report;
	uint32_t d = 0;
	char buf[4][32];
	int r = state_set_metar(s, report, m, &d, err, err_size);

	if (r < 0)
		return r;
	*dirty |= d;
	note->given = 1;
	weather_get(&s->weather.in, "visibility_km", buf[0], sizeof(buf[0]));
	weather_get(&s->weather.in, "relative_humidity", buf[1], sizeof(buf[1]));
	weather_get(&s->weather.in, "aerosol", buf[2], sizeof(buf[2]));
	weather_get(&s->weather.in, "cloud_oktas", buf[3], sizeof(buf[3]));
	size_t o = (size_t)snprintf(note->applied, sizeof(note->applied),
				    "visibility_km=%s relative_humidity=%s aerosol=%s cloud_oktas=%s",
				    buf[0], buf[1], buf[2], buf[3]);
	if (isfinite(m->qnh_hpa) && o < sizeof(note->applied))
		o += (size_t)snprintf(note->applied + o, sizeof(note->applied) - o,
				      " pressure_mbar=%.9g", s->clock.pressure_mbar);
	if (isfinite(m->temperature_c) && o < sizeof(note->applied))
		snprintf(note->applied + o, sizeof(note->applied) - o, " temperature_c=%.9g",
			 s->clock.temperature_c);
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
