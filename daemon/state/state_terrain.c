/* state_terrain.c - the terrain in the sky's state: the hooks of its keys
 * (the path, which reads the file; the content hash, which a follower
 * checks its own file against), the cross-key rule and the way back from
 * the state to the heights. The file and the field: daemon/terrain,
 * proto/skyterrain.h, docs/terrain.md. */
#include "state_internal.h"

#include <errno.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "terrain.h"

_Static_assert(STATE_TERRAIN_PATH_MAX == TERRAIN_PATH_MAX, "one bound on a terrain path");

bool state_terrain_set(const struct sky_state *s)
{
	return s->terrain.path[0] != 0;
}

static bool no_path(const char *v)
{
	return !*v || strcmp(v, "none") == 0;
}

/* terrain=PATH|none: reads the file (terrain_load) and keeps what it
 * held; refused whole, naming the file and why, when it cannot be read
 * as a height field: the state keeps the field it had. */
int state_set_terrain(struct sky_state *s, const struct state_key *k, const char *v,
		      uint32_t *ret_dirty, char *err, size_t err_size)
{
	bool had = state_terrain_set(s);
	char why[256];

	if (no_path(v)) {
		s->terrain.path[0] = 0;
		s->terrain.hash = 0;
		s->terrain.width = s->terrain.height = 0;
	} else {
		struct terrain *t;
		int r = terrain_load(v, &t, why, sizeof(why));
		if (r < 0) {
			snprintf(err, err_size, "%s: %s", k->name, why);
			return r == -EFBIG ? -ERANGE : -EINVAL;
		}
		snprintf(s->terrain.path, sizeof(s->terrain.path), "%s", v);
		s->terrain.hash = terrain_hash(t);
		s->terrain.width = terrain_width(t);
		s->terrain.height = terrain_height(t);
		terrain_unref(t);
	}
	if (!had && !state_terrain_set(s))
		*ret_dirty = 0;
	return 0;
}

int state_get_terrain(const struct sky_state *s, const struct state_key *k, char *buf, size_t n)
{
	(void)k;
	snprintf(buf, n, "%s", state_terrain_set(s) ? s->terrain.path : "none");
	return 0;
}

/* terrain_extent_km, terrain_height_m: nothing changes while no field is
 * set. */
int state_set_terrain_key(struct sky_state *s, const struct state_key *k, const char *v,
			  uint32_t *ret_dirty, char *err, size_t err_size)
{
	int r = state_key_parse(k, v, (char *)s + k->offset, err, err_size);

	if (r == 0 && !state_terrain_set(s))
		*ret_dirty = 0;
	return r;
}

/* terrain_hash: what the field read holds. Set, it is a check and changes
 * nothing: the file here must hold what the hash says (a replicated
 * state carries the controller's, so a follower with another file
 * refuses that state and says why). */
int state_set_terrain_hash(struct sky_state *s, const struct state_key *k, const char *v,
			   uint32_t *ret_dirty, char *err, size_t err_size)
{
	uint64_t want = 0;

	*ret_dirty = 0;
	if (strcmp(v, "none") != 0) {
		size_t n = strspn(v, "0123456789abcdefABCDEF");
		if (n != 16 || v[n])
			return ERR("%s: '%s' is not none or 16 hexadecimal digits", k->name, v);
		want = strtoull(v, NULL, 16);
	}
	if (!state_terrain_set(s)) {
		if (strcmp(v, "none") != 0)
			return ERR("%s: %s names a field, but no terrain is set", k->name, v);
		return 0;
	}
	if (strcmp(v, "none") == 0 || want != s->terrain.hash)
		return ERR("%s: '%s' here holds %016" PRIx64 ", not %s: every host needs the same file",
			   k->name, s->terrain.path, s->terrain.hash, v);
	return 0;
}

int state_get_terrain_hash(const struct sky_state *s, const struct state_key *k, char *buf,
			   size_t n)
{
	(void)k;
	if (state_terrain_set(s))
		snprintf(buf, n, "%016" PRIx64, s->terrain.hash);
	else
		snprintf(buf, n, "none");
	return 0;
}

int state_terrain_validate(const struct sky_state *s, char *err, size_t err_size)
{
	double shell_m = (s->atmo.top_radius_km - s->atmo.bottom_radius_km) * 1000.0;

	if (state_terrain_set(s) && !(s->terrain.height_m < shell_m))
		return ERR_RANGE("terrain_height_m: %g reaches the atmosphere's top (%g m above the ground)",
				 s->terrain.height_m, shell_m);
	return 0;
}

int state_terrain_get(const struct sky_state *s, struct terrain **ret_terrain,
		      struct skyterrain *ret_view, char *err, size_t err_size)
{
	struct terrain *t;
	int r;

	if (!state_terrain_set(s))
		return ERR_UNKNOWN("terrain: none set");
	if ((r = terrain_load(s->terrain.path, &t, err, err_size)) < 0)
		return r;
	if (terrain_hash(t) != s->terrain.hash) {
		snprintf(err, err_size, "'%s' changed since it was set: it holds %016" PRIx64 ", not %016" PRIx64,
			 s->terrain.path, terrain_hash(t), s->terrain.hash);
		terrain_unref(t);
		return -EINVAL;
	}
	terrain_view(t, s->terrain.extent_km, s->terrain.height_m * 1e-3, ret_view);
	*ret_terrain = t;
	return 0;
}
