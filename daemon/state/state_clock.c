/* state_clock.c - the simulated clock in the sky's state: the hooks of its
 * keys (utc and the lights' modes), who drives the lights when a key is
 * set, and the simulated time of a state. daemon/srv/drive.c computes the
 * lights from it. */
#include "state_internal.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "simclock.h"

double state_clock_utc_s(const struct sky_state *s, double mono_s)
{
	const struct state_clock *c = &s->clock;

	if (isnan(c->anchor_utc_s))
		return NAN;
	return c->anchor_utc_s + c->rate * (mono_s - c->anchor_mono_s);
}

void state_clock_rebase(struct sky_state *next, const struct sky_state *cur, double mono_s)
{
	struct state_clock *n = &next->clock;
	const struct state_clock *c = &cur->clock;

	if (n->rate == c->rate || isnan(c->anchor_utc_s) ||
	    memcmp(&n->anchor_utc_s, &c->anchor_utc_s, sizeof(double)) ||
	    n->anchor_mono_s != c->anchor_mono_s)
		return;
	n->anchor_utc_s = state_clock_utc_s(cur, mono_s);
	n->anchor_mono_s = mono_s;
}

/* A clock that was never set starts at the real time, so that naming only
 * a place shows that place's sky now. */
static void clock_anchor_now(struct state_clock *c)
{
	double real_s, mono_s;

	simclock_read_clocks(&real_s, &mono_s);
	c->anchor_utc_s = real_s;
	c->anchor_mono_s = mono_s;
}

int state_set_utc(struct sky_state *s, const struct state_key *k, const char *v,
		  uint32_t *ret_dirty, char *err, size_t err_size)
{
	struct state_clock *c = &s->clock;
	double utc_s, mono_s;

	if (strcmp(v, "now") == 0) {
		clock_anchor_now(c);
		return 0;
	}
	if (simclock_parse_utc(v, &utc_s) < 0)
		return ERR("%s: '%s' is not now or an ISO 8601 UTC time such as 2026-06-21T18:30:00Z (a real date, a zone)",
			   k->name, v);
	simclock_read_clocks(NULL, &mono_s);
	c->anchor_utc_s = utc_s;
	c->anchor_mono_s = mono_s;
	return 0;
}

/* The simulated time now. */
int state_get_utc(const struct sky_state *s, const struct state_key *k, char *buf, size_t n)
{
	double mono_s;

	simclock_read_clocks(NULL, &mono_s);
	double utc_s = state_clock_utc_s(s, mono_s);
	if (isnan(utc_s))
		snprintf(buf, n, "none");
	else if (simclock_format_utc(utc_s, buf, n) < 0)
		snprintf(buf, n, "%.3f", utc_s);	/* outside years 0..9999 */
	return 0;
}

int state_set_light_mode(struct sky_state *s, const struct state_key *k, const char *v,
			 uint32_t *ret_dirty, char *err, size_t err_size)
{
	int m;
	int r = state_key_parse(k, v, &m, err, err_size);

	if (r < 0)
		return r;
	*(int *)((char *)s + k->offset) = m;
	if (m == STATE_CLOCK && isnan(s->clock.anchor_utc_s))
		clock_anchor_now(&s->clock);
	return 0;
}

/* Naming a time or a place hands both lights to the clock; setting what
 * the clock computes for a light takes that light back. */
void state_clock_hand_lights(struct sky_state *s, enum state_key_hands hands)
{
	struct state_clock *c = &s->clock;

	switch (hands) {
	case STATE_HANDS_NONE:
		break;
	case STATE_HANDS_TO_CLOCK:
		c->sun_mode = c->moon_mode = STATE_CLOCK;
		if (isnan(c->anchor_utc_s))
			clock_anchor_now(c);
		break;
	case STATE_HANDS_SUN_TO_USER:
		c->sun_mode = STATE_MANUAL;
		break;
	case STATE_HANDS_MOON_TO_USER:
		c->moon_mode = STATE_MANUAL;
		break;
	}
}
