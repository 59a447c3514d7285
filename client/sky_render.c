/* sky_render.c - libsky's CPU evaluation of a view: the sampling functions
 * (through proto/skysample.h, the code the daemon's `sample` verbs use) and
 * rendering to an RGB float image in three projections. Touches no client
 * state, so every function here is thread-safe on a stable view. */
#include <errno.h>
#include <math.h>
#include <stddef.h>

#include "sky.h"
#include "skysample.h"

#define DEG (SKYMAP_PI / 180.0)
#define LIMB_U 0.6			/* linear limb-darkening coefficient, visible band */

static int view_table(const struct sky_view *v, uint32_t id, struct skysample_table *ret)
{
	if (!v || !v->header || !v->slot_base)
		return -EINVAL;
	if (!(v->valid_tables & SKY_TABLE_BIT(id)))
		return -ENODATA;
	return skysample_table_from_slot(v->header, v->slot_base, id, ret) < 0 ? -ENODATA : 0;
}

int sky_sample_transmittance(const struct sky_view *v, double altitude_km, double mu,
			     double ret_rgb[3])
{
	struct skysample_table t;
	if (!ret_rgb || !isfinite(altitude_km) || !isfinite(mu))
		return -EINVAL;
	int r = view_table(v, SKY_TABLE_TRANSMITTANCE, &t);
	if (r < 0)
		return r;
	skysample_transmittance(&t, &v->slot->state, altitude_km, mu, ret_rgb);
	return 0;
}

/* Adds the lit disks in flags to rgb for the unit direction dir. */
static void add_disks(const struct skysample_table *trans, const struct sky_shm_state *st,
		      const double dir[3], unsigned flags, double rgb[3])
{
	if (flags & SKY_SAMPLE_SUN_DISK)
		skysample_add_disk(trans, st, st->sun_direction, st->sun_illuminance_lx,
				   st->sun_angular_radius_rad, dir,
				   (flags & SKY_SAMPLE_LIMB_DARKENING) ? LIMB_U : 0.0, rgb);
	if (flags & SKY_SAMPLE_MOON_DISK)
		skysample_add_disk(trans, st, st->moon_direction, st->moon_illuminance_lx,
				   st->moon_angular_radius_rad, dir, 0.0, rgb);
}

static int sky_tables(const struct sky_view *v, unsigned flags, struct skysample_table *sky,
		      struct skysample_table *trans)
{
	if (flags & ~(unsigned)(SKY_SAMPLE_SUN_DISK | SKY_SAMPLE_MOON_DISK | SKY_SAMPLE_LIMB_DARKENING))
		return -EINVAL;
	int r = view_table(v, SKY_TABLE_SKYVIEW, sky);
	if (r == 0 && (flags & (SKY_SAMPLE_SUN_DISK | SKY_SAMPLE_MOON_DISK)))
		r = view_table(v, SKY_TABLE_TRANSMITTANCE, trans);
	return r;
}

int sky_sample_sky(const struct sky_view *v, double elevation_deg, double azimuth_deg,
		   unsigned flags, double ret_rgb[3])
{
	struct skysample_table sky, trans;
	if (!ret_rgb || !isfinite(elevation_deg) || !isfinite(azimuth_deg) ||
	    fabs(elevation_deg) > 90.0)
		return -EINVAL;
	int r = sky_tables(v, flags, &sky, &trans);
	if (r < 0)
		return r;
	double rgb[3], dir[3];
	skysample_sky(&sky, &v->slot->state, elevation_deg * DEG, azimuth_deg * DEG, rgb);
	skysample_direction(elevation_deg * DEG, azimuth_deg * DEG, dir);
	add_disks(&trans, &v->slot->state, dir, flags, rgb);
	for (int c = 0; c < 3; c++)
		ret_rgb[c] = rgb[c];
	return 0;
}

/* The aerial perspective of the state's camera (name NULL: the aerial
 * table) or of a registered view, with the camera it belongs to and, for a
 * view of form panorama, the panorama (NULL for a volume). */
struct aerial_src {
	struct skysample_table t;
	const struct sky_shm_panorama *panorama;
	const double *fwd, *right, *up;
	double tan_half, aspect;
};

static int aerial_source(const struct sky_view *v, const char *name, struct aerial_src *ret)
{
	const struct sky_shm_view *vw = NULL;
	int r;
	if (!name)
		r = view_table(v, SKY_TABLE_AERIAL, &ret->t);
	else if (!v || !v->header || !v->slot_base)
		r = -EINVAL;
	else
		r = skysample_view_from_slot(v->header, v->slot_base, name, &ret->t, &vw);
	if (r < 0)
		return r;
	const struct sky_shm_state *st = &v->slot->state;
	ret->panorama = vw && vw->form == SKY_VIEW_PANORAMA ? &vw->panorama : NULL;
	ret->fwd = vw ? vw->camera_forward : st->camera_forward;
	ret->right = vw ? vw->camera_right : st->camera_right;
	ret->up = vw ? vw->camera_up : st->camera_up;
	ret->tan_half = tan(0.5 * (vw ? vw->camera_vfov_rad : st->camera_vfov_rad));
	ret->aspect = vw ? vw->camera_aspect : st->camera_aspect;
	return 0;
}

/* Samples src toward the unit direction dir (panorama) or at the screen
 * position (su, sv) (volume); dir may be NULL for a volume. */
static void aerial_sample(const struct sky_view *v, const struct aerial_src *src, const double dir[3],
			  double su, double sv, double distance_km, double ret_rgb[3],
			  double *ret_transmittance)
{
	double rgb[3], tr;
	if (src->panorama)
		skysample_panorama(&src->t, src->panorama, &v->slot->state, dir, distance_km, rgb, &tr);
	else
		skysample_aerial(&src->t, &v->slot->state, su, sv, distance_km, rgb, &tr);
	for (int c = 0; c < 3; c++)
		ret_rgb[c] = rgb[c];
	if (ret_transmittance)
		*ret_transmittance = tr;
}

/* An aerial perspective sample at a screen position of the state's camera
 * (name NULL) or a registered view's: for a panorama, toward the direction
 * through that position. */
static int aerial_at(const struct sky_view *v, const char *name, double screen_u, double screen_v,
		     double distance_km, double ret_rgb[3], double *ret_transmittance)
{
	struct aerial_src src;
	if (!ret_rgb || !isfinite(screen_u) || !isfinite(screen_v) || !isfinite(distance_km) ||
	    distance_km < 0.0)
		return -EINVAL;
	int r = aerial_source(v, name, &src);
	if (r < 0)
		return r;
	double dir[3] = { 0.0, 0.0, 1.0 };
	if (src.panorama)
		skysample_screen_dir(src.fwd, src.right, src.up, src.tan_half, src.aspect, screen_u,
				     screen_v, dir);
	aerial_sample(v, &src, dir, screen_u, screen_v, distance_km, ret_rgb, ret_transmittance);
	return 0;
}

int sky_sample_aerial(const struct sky_view *v, double screen_u, double screen_v,
		      double distance_km, double ret_rgb[3], double *ret_transmittance)
{
	return aerial_at(v, NULL, screen_u, screen_v, distance_km, ret_rgb, ret_transmittance);
}

int sky_sample_view_aerial_dir(const struct sky_view *v, const char *name, const double dir[3],
			       double distance_km, double ret_rgb[3], double *ret_transmittance)
{
	struct aerial_src src;
	if (!ret_rgb || !dir || !isfinite(distance_km) || distance_km < 0.0)
		return -EINVAL;
	double n = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
	if (!isfinite(n) || !(n > 0.0))
		return -EINVAL;
	double d[3] = { dir[0] / n, dir[1] / n, dir[2] / n }, su = 0.0, sv = 0.0;
	int r = aerial_source(v, name, &src);
	if (r < 0)
		return r;
	if (!src.panorama)
		skysample_screen_uv(src.fwd, src.right, src.up, src.tan_half, src.aspect, d, &su, &sv);
	aerial_sample(v, &src, d, su, sv, distance_km, ret_rgb, ret_transmittance);
	return 0;
}

int sky_view_aerial_table(const struct sky_view *v, const char *name, const void **ret_texels,
			  size_t *ret_bytes)
{
	struct skysample_table t;
	if (!v || !v->header || !v->slot_base || !name || !ret_texels)
		return -EINVAL;
	int r = skysample_view_from_slot(v->header, v->slot_base, name, &t, NULL);
	if (r < 0)
		return r;
	*ret_texels = t.texels;
	if (ret_bytes)
		*ret_bytes = (size_t)t.width * t.height * t.depth *
			     (t.format == SKY_FORMAT_RGBA16F ? 8 : 16);
	return 0;
}

int sky_table_scale(const struct sky_view *v, uint32_t table_id, double *ret_scale)
{
	struct skysample_table t;
	if (!ret_scale || table_id >= SKY_SHM_MAX_TABLES)
		return -EINVAL;
	int r = view_table(v, table_id, &t);
	if (r < 0)
		return r;
	*ret_scale = t.format == SKY_FORMAT_RGBA16F ? ldexp(1.0, t.rgb_scale_log2) : 1.0;
	return 0;
}

int sky_sample_view_aerial(const struct sky_view *v, const char *name, double screen_u,
			   double screen_v, double distance_km, double ret_rgb[3],
			   double *ret_transmittance)
{
	if (!name)
		return -EINVAL;
	return aerial_at(v, name, screen_u, screen_v, distance_km, ret_rgb, ret_transmittance);
}

int sky_sample_sun(const struct sky_view *v, double ret_lx[3])
{
	struct skysample_table t;
	if (!ret_lx)
		return -EINVAL;
	int r = view_table(v, SKY_TABLE_TRANSMITTANCE, &t);
	if (r < 0)
		return r;
	skysample_sun(&t, &v->slot->state, ret_lx);
	return 0;
}

int sky_sample_ambient(const struct sky_view *v, double ret_lx[3])
{
	struct skysample_table t;
	if (!ret_lx)
		return -EINVAL;
	int r = view_table(v, SKY_TABLE_SKYVIEW, &t);
	if (r < 0)
		return r;
	skysample_ambient(&t, &v->slot->state, ret_lx);
	return 0;
}

/* ---- projections ---------------------------------------------------------- */

static int check_params(const struct sky_render_params *p)
{
	if (!p || !p->width || !p->height || !isfinite(p->yaw_deg))
		return -EINVAL;
	switch (p->projection) {
	case SKY_PROJECTION_EQUIRECT:
	case SKY_PROJECTION_FISHEYE:
		return 0;
	case SKY_PROJECTION_PERSPECTIVE:
		if (!(p->vfov_deg > 0.0 && p->vfov_deg < 180.0) || !isfinite(p->pitch_deg) ||
		    !isfinite(p->roll_deg))
			return -EINVAL;
		return 0;
	}
	return -EINVAL;
}

/* The camera basis of the perspective projection: forward, right, up. */
static void camera_basis(const struct sky_render_params *p, double f[3], double r[3], double u[3])
{
	double yaw = p->yaw_deg * DEG, pitch = p->pitch_deg * DEG, roll = p->roll_deg * DEG;
	skysample_direction(pitch, yaw, f);
	double r0[3] = { cos(yaw), -sin(yaw), 0.0 };
	/* up0 = r0 x f */
	double u0[3] = { r0[1] * f[2] - r0[2] * f[1], r0[2] * f[0] - r0[0] * f[2],
			 r0[0] * f[1] - r0[1] * f[0] };
	for (int i = 0; i < 3; i++) {
		r[i] = cos(roll) * r0[i] + sin(roll) * u0[i];
		u[i] = cos(roll) * u0[i] - sin(roll) * r0[i];
	}
}

int sky_render_direction(const struct sky_render_params *p, double x, double y, double ret_dir[3])
{
	if (check_params(p) < 0 || !ret_dir || !isfinite(x) || !isfinite(y))
		return -EINVAL;
	double w = p->width, h = p->height;
	switch (p->projection) {
	case SKY_PROJECTION_EQUIRECT:
		skysample_direction(0.5 * SKYMAP_PI - SKYMAP_PI * y / h, 2.0 * SKYMAP_PI * x / w, ret_dir);
		return 1;
	case SKY_PROJECTION_PERSPECTIVE: {
		double f[3], r[3], u[3];
		camera_basis(p, f, r, u);
		skysample_screen_dir(f, r, u, tan(0.5 * p->vfov_deg * DEG), w / h, x / w, 1.0 - y / h,
				     ret_dir);
		return 1;
	}
	case SKY_PROJECTION_FISHEYE: {
		double rad = 0.5 * (w < h ? w : h);
		double dx = (x - 0.5 * w) / rad, dy = (0.5 * h - y) / rad;
		double rho = sqrt(dx * dx + dy * dy);
		if (rho > 1.0)
			return 0;
		double az = p->yaw_deg * DEG + atan2(dx, -dy);
		skysample_direction(0.5 * SKYMAP_PI * (1.0 - rho), az, ret_dir);
		return 1;
	}
	}
	return -EINVAL;
}

int sky_render_position(const struct sky_render_params *p, const double dir[3], double *ret_x,
			double *ret_y)
{
	if (check_params(p) < 0 || !dir || !ret_x || !ret_y)
		return -EINVAL;
	double w = p->width, h = p->height;
	double el = asin(skymap_clamp(dir[2], -1.0, 1.0)), az = atan2(dir[0], dir[1]);
	switch (p->projection) {
	case SKY_PROJECTION_EQUIRECT: {
		double a = az / (2.0 * SKYMAP_PI);
		*ret_x = (a - floor(a)) * w;
		*ret_y = (0.5 * SKYMAP_PI - el) / SKYMAP_PI * h;
		return 1;
	}
	case SKY_PROJECTION_PERSPECTIVE: {
		double f[3], r[3], u[3], t = tan(0.5 * p->vfov_deg * DEG);
		camera_basis(p, f, r, u);
		double df = 0.0, dr = 0.0, du = 0.0;
		for (int i = 0; i < 3; i++) {
			df += dir[i] * f[i];
			dr += dir[i] * r[i];
			du += dir[i] * u[i];
		}
		if (df <= 0.0)
			return 0;
		*ret_x = (dr / df / (t * (w / h)) + 1.0) * 0.5 * w;
		*ret_y = (1.0 - du / df / t) * 0.5 * h;
		return 1;
	}
	case SKY_PROJECTION_FISHEYE: {
		if (el < 0.0)
			return 0;
		double rad = 0.5 * (w < h ? w : h);
		double rho = 1.0 - el / (0.5 * SKYMAP_PI), a = az - p->yaw_deg * DEG;
		*ret_x = 0.5 * w + rad * rho * sin(a);
		*ret_y = 0.5 * h + rad * rho * cos(a);
		return 1;
	}
	}
	return -EINVAL;
}

int sky_render(const struct sky_view *v, const struct sky_render_params *p, float *ret_rgb)
{
	struct skysample_table sky, trans;
	if (check_params(p) < 0 || !ret_rgb)
		return -EINVAL;
	int r = sky_tables(v, p->flags, &sky, &trans);
	if (r < 0)
		return r;
	const struct sky_shm_state *st = &v->slot->state;
	for (uint32_t y = 0; y < p->height; y++) {
		for (uint32_t x = 0; x < p->width; x++) {
			double dir[3], rgb[3] = { 0.0, 0.0, 0.0 };
			float *o = ret_rgb + ((size_t)y * p->width + x) * 3;
			if (sky_render_direction(p, x + 0.5, y + 0.5, dir) == 1) {
				double el = asin(skymap_clamp(dir[2], -1.0, 1.0));
				double az = atan2(dir[0], dir[1]);
				skysample_sky(&sky, st, el, az, rgb);
				add_disks(&trans, st, dir, p->flags, rgb);
			}
			for (int c = 0; c < 3; c++)
				o[c] = (float)rgb[c];
		}
	}
	return 0;
}
