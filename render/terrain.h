/* terrain.h - the example client's ground: a procedural height field (value
 * noise) around the observer, as a triangle mesh dense near the eye and
 * coarse far away. Pure CPU, no Vulkan. */
#ifndef SKYRENDER_TERRAIN_H
#define SKYRENDER_TERRAIN_H

#include <stddef.h>
#include <stdint.h>

/* Positions in km in the observer's east-north-up frame with the ground
 * under the observer at z = 0 (the planet's curvature included), and the
 * unit normal. */
struct terrain_vertex {
	float position_km[3];
	float normal[3];
};

struct terrain_mesh {
	struct terrain_vertex *vertices;
	uint32_t *indices;		/* triangles, counter-clockwise seen from above */
	uint32_t vertex_count, index_count;
};

/* Builds a grid of n x n vertices (n >= 2) reaching radius_km from the
 * observer, for a planet of bottom_radius_km; seed picks the hills. The
 * ground stays a few metres under the eye near the observer and rises into
 * hills (up to about a kilometre) a few kilometres away. 0 or -ENOMEM /
 * -EINVAL; the caller frees the mesh with terrain_mesh_finish(). */
int terrain_mesh_init(uint32_t n, double radius_km, double bottom_radius_km, uint32_t seed,
		      struct terrain_mesh *ret);
void terrain_mesh_finish(struct terrain_mesh *m);

/* The height of the ground (km, before the curvature) at (x, y) km. */
double terrain_height_km(double x_km, double y_km, uint32_t seed);

#endif
