/* media.h - what the truth takes of a sky state's clouds and terrain: the
 * path tracer's scene (struct pt_scene) made from the state's cloud
 * layers and its terrain file, and synthetic height fields written as
 * SKYTERRAIN16 files for the accuracy scenes and the stiff cases, so that
 * no height field is committed. */
#ifndef SKYD_MEDIA_H
#define SKYD_MEDIA_H

#include <stddef.h>
#include <stdint.h>

#include "pt.h"
#include "state.h"

struct terrain;

/* A scene and the field its terrain view reads, held while it is used. */
struct media {
	struct pt_scene scene;
	struct terrain *terrain;	/* NULL: none */
	struct skyterrain view;
};

/* The clouds (state_cloud_layers_double, the wind's offset of
 * state_cloud_offset_km) and the terrain (state_terrain_get) of s, the
 * view PT_VIEW_AIR. Returns 0, or -errno with err (a terrain file gone or
 * changed). Release with media_finish. */
int media_from_state(const struct sky_state *s, struct media *ret, char *err, size_t err_size);
void media_finish(struct media *m);
/* Whether s has anything a scene holds: a drawn layer or a terrain. */
bool media_present(const struct sky_state *s);

/* The synthetic height fields. */
enum media_terrain {
	/* An east-west ridge 6 km south of the site, 1 at its crest, 40 km
	 * long with its ends faded (256 x 256 texels): at 1500 m and a low
	 * sun in the south its shadow covers the valley. */
	MEDIA_RIDGE = 0,
	/* A cliff at the site's feet: 0 to its west, 1 to its east, the face
	 * between the centres 16 and 47 m east of the site (64 x 64 texels
	 * over 2 km). */
	MEDIA_CLIFF = 1,
	MEDIA_N_TERRAINS = 2,
};
extern const char *const media_terrain_names[MEDIA_N_TERRAINS];

/* The path of terrain's file, written the first time it is asked for into
 * a directory of this process under $TMPDIR (removed at exit); NULL when
 * it cannot be written (errno says why). Not thread-safe. */
const char *media_terrain_path(enum media_terrain terrain);

/* The key=value pair kv with a synthetic field's name ("terrain=@ridge",
 * "terrain=@cliff") made the path of its file in buf: kv itself when it
 * names none; NULL when the name is unknown (errno EINVAL) or the file
 * cannot be written (errno says why). */
const char *media_expand_key(const char *kv, char *buf, size_t size);

/* A SKYTERRAIN16 file of width x width texels at path. 0 or -errno. */
int media_write_raw(const char *path, const uint16_t *texels, uint32_t width);

#endif
