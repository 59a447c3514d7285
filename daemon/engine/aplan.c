/* aplan.c - the aerial plan of a state (aplan.h): cameras grouped by eye
 * point, the volumes and panoramas they need, and each panorama's
 * directions. */
#include "aplan.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "skymap.h"
#include "skyproto.h"

static void put4(float d[4], double a, double b, double c, double w)
{
	d[0] = (float)a;
	d[1] = (float)b;
	d[2] = (float)c;
	d[3] = (float)w;
}

static double dot3(const double a[3], const double b[3])
{
	return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static void cross3(const double a[3], const double b[3], double ret[3])
{
	ret[0] = a[1] * b[2] - a[2] * b[1];
	ret[1] = a[2] * b[0] - a[0] * b[2];
	ret[2] = a[0] * b[1] - a[1] * b[0];
}

static void normalize3(double v[3])
{
	double n = sqrt(dot3(v, v));
	for (int i = 0; i < 3; i++)
		v[i] /= n;
}

/* The rotation from the site's local frame (east, north, up) to the one at
 * east_km, north_km from it along the ground (state_view): the local
 * vertical there, and true north for a site at lat_deg on a sphere of
 * bottom_radius_km. */
static void view_frame(double lat_deg, double bottom_radius_km, double east_km, double north_km,
		    double ret[3][3])
{
	const double deg = SKYMAP_PI / 180.0;
	double phi = lat_deg * deg, d = hypot(east_km, north_km), beta = atan2(east_km, north_km);
	double theta = d / bottom_radius_km;
	/* Earth-fixed axes: x to the site's meridian, z to the pole. */
	double u0[3] = { cos(phi), 0, sin(phi) }, e0[3] = { 0, 1, 0 }, n0[3] = { -sin(phi), 0, cos(phi) };
	double up[3], east[3], north[3], pole[3] = { 0, 0, 1 };
	for (int i = 0; i < 3; i++)
		up[i] = cos(theta) * u0[i] + sin(theta) * (sin(beta) * e0[i] + cos(beta) * n0[i]);
	cross3(pole, up, east);
	if (dot3(east, east) < 1e-18) {
		/* At a pole north has no direction: the site's north carried
		 * along the great circle, which is where the path arrives from. */
		double t[3];
		for (int i = 0; i < 3; i++)
			t[i] = cos(theta) * (sin(beta) * e0[i] + cos(beta) * n0[i]) - sin(theta) * u0[i];
		double side[3];
		cross3(up, t, side);	/* left of the path */
		for (int i = 0; i < 3; i++)
			north[i] = cos(beta) * t[i] + sin(beta) * side[i];
		cross3(north, up, east);
	}
	normalize3(east);
	cross3(up, east, north);
	/* Row r, column c: local axis r on the site's axis c (east, north, up). */
	const double *local[3] = { east, north, up }, *site[3] = { e0, n0, u0 };
	for (int r = 0; r < 3; r++)
		for (int c = 0; c < 3; c++)
			ret[r][c] = dot3(local[r], site[c]);
}

static void rotate(const double m[3][3], const double v[3], double ret[3])
{
	for (int r = 0; r < 3; r++)
		ret[r] = m[r][0] * v[0] + m[r][1] * v[1] + m[r][2] * v[2];
}

/* Camera i of s: 0 the state's camera, then the views. */
static void camera_of(const struct sky_state *s, const struct state_lights *lights, uint32_t i,
		      struct aplan_camera *ret)
{
	const struct state_camera *c = i ? &s->views[i - 1].camera : &s->camera;
	double h = i && !isnan(s->views[i - 1].altitude_km) ? s->views[i - 1].altitude_km : s->altitude_km;
	const double *sun = lights->sun, *moon = lights->moon;

	memset(ret, 0, sizeof(*ret));
	ret->h_km = h > 0.0 ? h : 0.0;
	ret->east_km = i ? s->views[i - 1].east_km : 0.0;
	ret->north_km = i ? s->views[i - 1].north_km : 0.0;
	state_camera_basis(c, ret->fwd, ret->right, ret->up);
	ret->tan_half = tan(c->vfov_deg * SKYMAP_PI / 360.0);
	ret->aspect = c->aspect;
	if (ret->east_km == 0.0 && ret->north_km == 0.0) {
		memcpy(ret->sun, sun, sizeof(ret->sun));
		memcpy(ret->moon, moon, sizeof(ret->moon));
		for (int k = 0; k < 3; k++)
			ret->site[k][k] = 1.0;
		return;
	}
	double m[3][3], rb = s->atmo.bottom_radius_km;
	view_frame(s->clock.lat_deg, rb, ret->east_km, ret->north_km, m);
	rotate(m, sun, ret->sun);
	rotate(m, moon, ret->moon);
	/* Row r of m is the eye's axis r in the site's frame; its ground
	 * point is rb up there less rb up at the site. */
	memcpy(ret->site, m, sizeof(m));
	for (int k = 0; k < 3; k++)
		ret->ground_km[k] = rb * m[2][k] - (k == 2 ? rb : 0.0);
}

static bool same_eye(const struct aplan_camera *a, const struct aplan_camera *b)
{
	return a->h_km == b->h_km && a->east_km == b->east_km && a->north_km == b->north_km;
}

/* The panorama's columns and rows for s's aerial size (one column more is
 * stored: panorama_mapping): three quarters of one volume's columns, half
 * its rows (48 x 16 for 32 x 32), which holds
 * tests/numerical/test_views.c's goal; 64 x 16 brings the 99th percentile of the
 * error on Mars from 9.2 to 7.3 % for a third more march
 * (docs/findings/engine.md). Never fewer than 48 x 16: the error is set by the
 * sky's curvature between the panorama's rays, not by the volume's size
 * (16 x 16 volumes from a 24 x 8 panorama read 2.8 % on average). */
static void panorama_size(const struct sky_state *s, uint32_t *ret_w, uint32_t *ret_h)
{
	const struct state_table_quality *q = &s->quality.t[STATE_AERIAL];
	uint32_t h = q->height / 2 > 16 ? q->height / 2 : 16;
	uint32_t w = 3 * q->width * q->height / (4 * h);
	*ret_w = w > 48 ? w : 48;
	*ret_h = h;
}

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return x < y ? -1 : x > y;
}

/* The azimuths and elevations of the column centres on the border of
 * volumes vol[i], i in members (a mask), as aerial_resample.comp places
 * them: a pinhole's directions cover the azimuths and elevations of its
 * border, unless the zenith or the nadir is inside, which sets
 * *ret_pole (1 zenith, -1 nadir; the full circle of azimuths). */
static uint32_t column_directions(const struct sky_state *s, const struct aplan_camera *vol,
				  uint32_t members, double *az, double *el, int *ret_pole)
{
	const struct state_table_quality *q = &s->quality.t[STATE_AERIAL];
	uint32_t n = 0;
	for (uint32_t i = 0; i < APLAN_CAMERAS; i++) {
		if (!(members & (1u << i)))
			continue;
		const struct aplan_camera *v = &vol[i];
		for (int pole = -1; pole <= 1; pole += 2) {
			double f = pole * v->fwd[2], nx = pole * v->right[2] / (f * v->tan_half * v->aspect);
			double ny = pole * v->up[2] / (f * v->tan_half);
			if (f > 0 && fabs(nx) <= 1.0 - 1.0 / q->width && fabs(ny) <= 1.0 - 1.0 / q->height)
				*ret_pole = pole;
		}
		for (uint32_t y = 0; y < q->height; y++) {
			bool edge = y == 0 || y + 1 == q->height;
			for (uint32_t x = 0; x < q->width; x += edge || q->width < 2 ? 1 : q->width - 1) {
				double nx = (x + 0.5) / q->width * 2.0 - 1.0, ny = (y + 0.5) / q->height * 2.0 - 1.0;
				double d[3];
				for (int k = 0; k < 3; k++)
					d[k] = v->fwd[k] + nx * v->tan_half * v->aspect * v->right[k] +
					       ny * v->tan_half * v->up[k];
				normalize3(d);
				az[n] = atan2(d[0], d[1]);
				el[n++] = asin(d[2] < -1.0 ? -1.0 : d[2] > 1.0 ? 1.0 : d[2]);
			}
		}
	}
	return n;
}

/* The panorama of the volumes in members, all on the eye of vol[first]:
 * its columns cover the arc of azimuths their column centres span (or the
 * full circle, from the sun's azimuth, when that is finer), its rows
 * their elevations, packed toward the eye's horizon, where the ground
 * cuts the rays short. Fills the mapping's two vec4s (aerial.comp). */
static void panorama_mapping(const struct sky_state *s, const struct aplan_camera *vol, uint32_t members,
			     uint32_t first, float m0[4], float m1[4])
{
	const struct state_table_quality *q = &s->quality.t[STATE_AERIAL];
	size_t cap = (size_t)2 * (q->width + q->height) * APLAN_CAMERAS;
	double *az = malloc(2 * cap * sizeof(double)), *el = az ? az + cap : NULL;
	uint32_t pw, ph, n = 0;
	/* Without the memory to place the columns: every direction. */
	double two_pi = 2.0 * SKYMAP_PI, start = 0.0, span = two_pi;
	double el_lo = -0.5 * SKYMAP_PI, el_hi = 0.5 * SKYMAP_PI;
	const struct aplan_camera *v = &vol[first];

	panorama_size(s, &pw, &ph);
	int pole = 0;
	if (az)
		n = column_directions(s, vol, members, az, el, &pole);
	if (n > 0) {
		el_lo = el_hi = el[0];
		for (uint32_t i = 1; i < n; i++) {
			el_lo = fmin(el_lo, el[i]);
			el_hi = fmax(el_hi, el[i]);
		}
		el_lo = pole < 0 ? -0.5 * SKYMAP_PI : el_lo;
		el_hi = pole > 0 ? 0.5 * SKYMAP_PI : el_hi;
		qsort(az, n, sizeof(double), cmp_double);
		double gap = az[0] + two_pi - az[n - 1];
		start = az[0];
		for (uint32_t i = 1; i < n; i++)
			if (az[i] - az[i - 1] > gap) {
				gap = az[i] - az[i - 1];
				start = az[i];
			}
		span = pole ? two_pi : two_pi - gap;
	}
	free(az);
	/* pw + 1 columns: around the full circle the last repeats the first,
	 * so that readers need no wrap; an arc ends on its first and last. */
	bool full = pole != 0 || n == 0;
	if (full)
		put4(m0, atan2(v->sun[0], v->sun[1]), two_pi / pw, 0, 0);
	else
		put4(m0, start, fmax(span / pw, 1e-6), 0, 0);
	double rb = s->atmo.bottom_radius_km;
	double el_h = -acos(rb / (rb + v->h_km));
	double e_lo = el_lo - el_h, e_hi = el_hi - el_h;
	double x_lo = copysign(sqrt(fabs(e_lo)), e_lo), x_hi = copysign(sqrt(fabs(e_hi)), e_hi);
	m0[2] = (float)x_lo;
	m0[3] = (float)fmax((x_hi - x_lo) / (ph - 1), 1e-6);
	put4(m1, el_h, pw + 1, ph, full ? 1.0 : 0.0);
}

void aplan_panorama_shape(const struct sky_state *s, uint32_t *ret_width, uint32_t *ret_height)
{
	uint32_t w, h;
	panorama_size(s, &w, &h);
	*ret_width = w + 1;
	*ret_height = h;
}

/* Groups the cameras of p by eye point: ret_group[i] holds the members of
 * the group camera i leads (0 for a camera that leads none). */
static void group_by_eye(const struct aplan *p, uint32_t ret_group[APLAN_CAMERAS])
{
	uint32_t grouped = 0;
	for (uint32_t i = 0; i < p->n_cameras; i++) {
		ret_group[i] = 0;
		if (grouped & (1u << i))
			continue;
		for (uint32_t j = i; j < p->n_cameras; j++)
			if (!(grouped & (1u << j)) && same_eye(&p->cam[i], &p->cam[j])) {
				ret_group[i] |= 1u << j;
				grouped |= 1u << j;
			}
	}
}

/* Adds the panorama of the group led by i, with members, and points its
 * readers at it: views of form panorama always, cameras of form volume
 * when shared. */
static void add_panorama(const struct sky_state *s, struct aplan *p, uint32_t i, uint32_t members,
			 int32_t view, bool share)
{
	struct aplan_panorama *o = &p->pano[p->n_panoramas];
	o->view = view;
	o->leader = i;
	panorama_mapping(s, p->cam, members, i, o->m0, o->m1);
	for (uint32_t c = 0; c < p->n_cameras; c++)
		if ((members & (1u << c)) && (p->volume[c] < 0 || share))
			p->panorama[c] = (int32_t)p->n_panoramas;
	p->n_panoramas++;
}

void aplan_make(const struct sky_state *s, bool share, struct aplan *ret)
{
	struct state_lights lights;

	state_lights_of(s, &lights);
	aplan_make_lit(s, &lights, share, ret);
}

void aplan_make_lit(const struct sky_state *s, const struct state_lights *lights, bool share,
		    struct aplan *ret)
{
	uint32_t group[APLAN_CAMERAS], pw, ph;

	memset(ret, 0, sizeof(*ret));
	ret->n_cameras = 1 + s->n_views;
	panorama_size(s, &pw, &ph);
	ret->width = pw + 1;
	ret->height = ph;
	ret->depth = s->quality.t[STATE_AERIAL].depth;
	for (uint32_t c = 0; c < ret->n_cameras; c++) {
		camera_of(s, lights, c, &ret->cam[c]);
		bool own = c == 0 || s->views[c - 1].form != SKY_VIEW_PANORAMA;
		ret->volume[c] = own ? (int32_t)ret->n_volumes++ : -1;
		ret->panorama[c] = -1;
	}
	group_by_eye(ret, group);
	/* Published panoramas first, so that their numbers do not depend on
	 * share; then the scratch ones of groups of two or more volumes. */
	for (uint32_t i = 0; i < ret->n_cameras; i++) {
		int32_t view = -1;
		for (uint32_t c = i; c < ret->n_cameras && view < 0; c++)
			if ((group[i] & (1u << c)) && ret->volume[c] < 0)
				view = (int32_t)c - 1;
		if (view >= 0)
			add_panorama(s, ret, i, group[i], view, share);
	}
	for (uint32_t i = 0; i < ret->n_cameras && share; i++)
		if ((group[i] & (group[i] - 1)) && ret->panorama[i] < 0)
			add_panorama(s, ret, i, group[i], -1, share);
}

void aplan_describe(const struct aplan *p, int32_t k, uint64_t offset, struct sky_shm_panorama *ret)
{
	const struct aplan_panorama *o = &p->pano[k];
	memset(ret, 0, sizeof(*ret));
	ret->offset = offset;
	ret->bytes = aplan_panorama_texels(p) * 16;
	ret->width = p->width;
	ret->height = p->height;
	ret->depth = p->depth;
	ret->full_circle = o->m1[3] > 0.5f;
	ret->azimuth0_rad = o->m0[0];
	ret->azimuth_step_rad = o->m0[1];
	ret->row0 = o->m0[2];
	ret->row_step = o->m0[3];
	ret->horizon_rad = o->m1[0];
}

uint64_t aplan_published_bytes(const struct aplan *p)
{
	uint32_t n = 0;
	while (n < p->n_panoramas && p->pano[n].view >= 0)
		n++;
	return n * aplan_panorama_texels(p) * 16;
}
