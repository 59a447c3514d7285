/* terrain.c - the procedural height field of the example client and its
 * mesh: a few octaves of value noise, flattened near the observer. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "terrain.h"

#define NEAR_FLAT_KM 1.5		/* the ground under the eye stays flat this far */
#define HILLS_FROM_KM 8.0		/* full hills from here on */
#define EYE_CLEARANCE_KM 0.002		/* the flat ground lies this far under the observer */

/* A hash of a lattice point to [0, 1). */
static double lattice(int32_t x, int32_t y, uint32_t seed)
{
	uint32_t h = (uint32_t)x * 0x8da6b343u ^ (uint32_t)y * 0xd8163841u ^ seed * 0xcb1ab31fu;
	h ^= h >> 15;
	h *= 0x2c1b3c6du;
	h ^= h >> 12;
	h *= 0x297a2d39u;
	h ^= h >> 15;
	return (h & 0xffffff) / 16777216.0;
}

/* Value noise with a smooth (quintic) blend, in [0, 1). */
static double value_noise(double x, double y, uint32_t seed)
{
	double fx = floor(x), fy = floor(y);
	int32_t ix = (int32_t)fx, iy = (int32_t)fy;
	double tx = x - fx, ty = y - fy;
	double sx = tx * tx * tx * (tx * (tx * 6.0 - 15.0) + 10.0);
	double sy = ty * ty * ty * (ty * (ty * 6.0 - 15.0) + 10.0);
	double a = lattice(ix, iy, seed), b = lattice(ix + 1, iy, seed);
	double c = lattice(ix, iy + 1, seed), d = lattice(ix + 1, iy + 1, seed);
	double lo = a + sx * (b - a), hi = c + sx * (d - c);
	return lo + sy * (hi - lo);
}

double terrain_height_km(double x_km, double y_km, uint32_t seed)
{
	double h = 0.0, amp = 0.6, freq = 1.0 / 12.0;
	for (int o = 0; o < 5; o++) {
		h += amp * value_noise(x_km * freq, y_km * freq, seed + (uint32_t)o);
		amp *= 0.45;
		freq *= 2.1;
	}
	double d = sqrt(x_km * x_km + y_km * y_km);
	double t = (d - NEAR_FLAT_KM) / (HILLS_FROM_KM - NEAR_FLAT_KM);
	t = t < 0.0 ? 0.0 : t > 1.0 ? 1.0 : t;
	t = t * t * (3.0 - 2.0 * t);
	return t * h * 2.0 - EYE_CLEARANCE_KM;
}

/* Grid coordinate s in [-1, 1] to km: quadratic, so that cells are small
 * near the observer, where the ground is seen at steep angles. */
static double grid_km(double s, double radius_km)
{
	return copysign(s * s, s) * radius_km;
}

int terrain_mesh_init(uint32_t n, double radius_km, double bottom_radius_km, uint32_t seed,
		      struct terrain_mesh *ret)
{
	if (n < 2 || n > 4096 || !(radius_km > 0.0) || !(bottom_radius_km > 0.0) || !ret)
		return -EINVAL;
	struct terrain_mesh m = { .vertex_count = n * n, .index_count = (n - 1) * (n - 1) * 6 };
	m.vertices = calloc(m.vertex_count, sizeof(*m.vertices));
	m.indices = calloc(m.index_count, sizeof(*m.indices));
	if (!m.vertices || !m.indices) {
		terrain_mesh_finish(&m);
		return -ENOMEM;
	}
	const double e = 0.01;		/* km, the step of the normal's differences */
	for (uint32_t j = 0; j < n; j++) {
		for (uint32_t i = 0; i < n; i++) {
			double x = grid_km(2.0 * i / (n - 1) - 1.0, radius_km);
			double y = grid_km(2.0 * j / (n - 1) - 1.0, radius_km);
			double h = terrain_height_km(x, y, seed);
			/* the sphere drops by d^2 / 2R below the tangent plane */
			double drop = (x * x + y * y) / (2.0 * bottom_radius_km);
			double hx = (terrain_height_km(x + e, y, seed) - terrain_height_km(x - e, y, seed)) / (2 * e);
			double hy = (terrain_height_km(x, y + e, seed) - terrain_height_km(x, y - e, seed)) / (2 * e);
			double nl = sqrt(hx * hx + hy * hy + 1.0);
			struct terrain_vertex *v = &m.vertices[j * n + i];
			v->position_km[0] = (float)x;
			v->position_km[1] = (float)y;
			v->position_km[2] = (float)(h - drop);
			v->normal[0] = (float)(-hx / nl);
			v->normal[1] = (float)(-hy / nl);
			v->normal[2] = (float)(1.0 / nl);
		}
	}
	uint32_t k = 0;
	for (uint32_t j = 0; j + 1 < n; j++) {
		for (uint32_t i = 0; i + 1 < n; i++) {
			uint32_t a = j * n + i, b = a + 1, c = a + n, d = c + 1;
			uint32_t tri[6] = { a, b, d, a, d, c };
			memcpy(&m.indices[k], tri, sizeof(tri));
			k += 6;
		}
	}
	*ret = m;
	return 0;
}

void terrain_mesh_finish(struct terrain_mesh *m)
{
	if (!m)
		return;
	free(m->vertices);
	free(m->indices);
	memset(m, 0, sizeof(*m));
}
