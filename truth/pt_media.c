/* pt_media.c - the path tracer's medium: the air's constituents, the
 * scene's cloud layers (proto/skycloud.h in double) and terrain
 * (proto/skyterrain.h), the geometry of the shell, the quadrature cells of
 * the view ray, and the two transport primitives every path uses: ratio
 * tracking of a shadow ray and delta tracking to the next collision, both
 * against a majorant that is piecewise constant along the ray (the air's
 * everywhere, plus each layer's extinction inside its shell). */
#include "pt_internal.h"

#include <errno.h>
#include <math.h>
#include <string.h>

/* 8-point Gauss-Legendre on [-1, 1], positive half. */
const double pt_gl_x[4] = { 0.1834346424956498, 0.5255324099163290,
				0.7966664774136267, 0.9602898564975363 };
const double pt_gl_w[4] = { 0.3626837833783620, 0.3137066458778873,
				0.2223810344533745, 0.1012285362903763 };

/* ---- vectors and random numbers ---- */

/* Orthonormal u, v completing n (Duff et al. 2017). */
void pt_basis(const double n[3], double u[3], double v[3])
{
	double s = copysign(1.0, n[2]);
	double a = -1.0 / (s + n[2]), b = n[0] * n[1] * a;
	u[0] = 1.0 + s * n[0] * n[0] * a;
	u[1] = s * b;
	u[2] = -s * n[0];
	v[0] = b;
	v[1] = s + n[1] * n[1] * a;
	v[2] = -n[1];
}

void pt_from_local(const double n[3], double cos_t, double phi, double ret[3])
{
	double u[3], v[3], s = sqrt(fmax(0.0, (1.0 - cos_t) * (1.0 + cos_t)));
	pt_basis(n, u, v);
	double cu = s * cos(phi), cv = s * sin(phi);
	for (int i = 0; i < 3; i++)
		ret[i] = cos_t * n[i] + cu * u[i] + cv * v[i];
}

void pt_direction(double elevation_deg, double azimuth_deg, double ret[3])
{
	double el = elevation_deg * PI / 180.0, az = azimuth_deg * PI / 180.0;
	ret[0] = cos(el) * sin(az);
	ret[1] = cos(el) * cos(az);
	ret[2] = sin(el);
}

void pt_rng_init(struct rng *r, uint64_t seed, uint64_t dir, uint64_t sample, int channel)
{
	const uint64_t k = 0x9e3779b97f4a7c15ull;
	r->key = pt_mix64(pt_mix64(pt_mix64(seed + k) + dir * k) + sample * 4 + (uint64_t)channel);
	r->ctr = 0;
}

/* ---- the medium ---- */

double pt_altitude(const struct medium *m, const double x[3])
{
	return sqrt(dot(x, x)) - m->rb;
}

static void air_densities(const struct medium *m, const double x[3], double ret[])
{
	double h = pt_altitude(m, x);
	for (int i = 0; i < m->n; i++)
		ret[i] = atmo_density(&m->c[i].density, h);
}

/* The cloud layers' extinction per km at x, each in its slot. */
static void cloud_densities(const struct medium *m, const double x[3], double rho[])
{
	double q[3] = { x[0], x[1], x[2] - m->rb };
	double h = skycloudd_altitude(m->rb, q);

	for (int i = 0; i < m->n_layers; i++)
		rho[CLOUD_SLOT(i)] = skycloudd_density(&m->layers[i], q[0], q[1], h, m->offset_km);
}

void pt_densities(const struct medium *m, const double x[3], double rho[])
{
	air_densities(m, x, rho);
	if (m->n_layers)
		cloud_densities(m, x, rho);
}

double pt_sigma_t(const struct medium *m, const double rho[], int ch)
{
	double st = 0.0;
	for (int i = 0; i < m->n; i++)
		st += m->ext[i][ch] * rho[i];
	for (int i = 0; i < m->n_layers; i++)
		st += rho[CLOUD_SLOT(i)];
	return st;
}

double pt_sigma_s(const struct medium *m, const double rho[], int ch)
{
	double s = 0.0;
	for (int i = 0; i < m->n; i++)
		s += m->c[i].scattering_per_km[ch] * rho[i];
	for (int i = 0; i < m->n_layers; i++)
		s += m->layer_albedo[i] * rho[CLOUD_SLOT(i)];
	return s;
}

/* Extinction at x of channel ch, the constituents without it skipped. */
static double extinction(const struct medium *m, const double x[3], int ch)
{
	double h = pt_altitude(m, x), s = 0.0;
	for (int i = 0; i < m->n; i++)
		if (m->ext[i][ch] > 0.0)
			s += m->ext[i][ch] * atmo_density(&m->c[i].density, h);
	if (m->n_layers) {
		double rho[PT_MEDIA];
		cloud_densities(m, x, rho);
		for (int i = 0; i < m->n_layers; i++)
			s += rho[CLOUD_SLOT(i)];
	}
	return s;
}

static double layer_value(const struct atmo_layer *l, double h)
{
	double d = l->exp_term * exp(l->exp_scale_per_km * h) + l->linear_per_km * h + l->constant;
	return d < 0.0 ? 0.0 : d > 1.0 ? 1.0 : d;
}

/* Largest density of one layer over [lo, hi]: a e^{sh} + l h + c is convex
 * or concave, so the maximum is at an end or at the stationary point. */
static double layer_max(const struct atmo_layer *l, double lo, double hi)
{
	double m = fmax(layer_value(l, lo), layer_value(l, hi));
	double a = l->exp_term, s = l->exp_scale_per_km, k = l->linear_per_km;
	if (a != 0.0 && s != 0.0 && k != 0.0 && -k / (a * s) > 0.0) {
		double h = log(-k / (a * s)) / s;
		if (h > lo && h < hi)
			m = fmax(m, layer_value(l, h));
	}
	return m;
}

static double profile_max(const struct atmo_profile *p, double shell_km)
{
	double w = p->layers[0].width_km, m = 0.0;
	if (w > 0.0)
		m = layer_max(&p->layers[0], 0.0, fmin(w, shell_km));
	if (w < shell_km)
		m = fmax(m, layer_max(&p->layers[1], fmax(w, 0.0), shell_km));
	return m;
}

static void add_kink(struct medium *m, double h, double shell_km)
{
	size_t cap = sizeof(m->kink_km) / sizeof(m->kink_km[0]);
	if (isfinite(h) && h > 0.0 && h < shell_km && (size_t)m->n_kinks < cap)
		m->kink_km[m->n_kinks++] = h;
}

/* Altitudes where a layer's clamp starts or stops acting, where the
 * quadrature must cut its cells. Mixed exponential-plus-linear layers have
 * no closed form and are left to the cell size. */
static void layer_kinks(struct medium *m, const struct atmo_layer *l, double shell_km)
{
	for (int v = 0; v <= 1; v++) {
		if (l->exp_term == 0.0 && l->linear_per_km != 0.0)
			add_kink(m, (v - l->constant) / l->linear_per_km, shell_km);
		else if (l->linear_per_km == 0.0 && l->exp_term != 0.0 &&
			 l->exp_scale_per_km != 0.0 && (v - l->constant) / l->exp_term > 0.0)
			add_kink(m, log((v - l->constant) / l->exp_term) / l->exp_scale_per_km,
				 shell_km);
	}
}

void pt_medium_init(struct medium *m, const struct atmo *a, const struct pt_sun *sun)
{
	double shell = a->top_radius_km - a->bottom_radius_km;

	memset(m, 0, sizeof(*m));
	m->rb = a->bottom_radius_km;
	m->rt = a->top_radius_km;
	m->n = a->n_constituents;
	m->c = a->c;
	m->dh_max_km = 1e300;
	for (int i = 0; i < m->n; i++) {
		const struct atmo_constituent *c = &a->c[i];
		double dmax = profile_max(&c->density, shell);
		for (int ch = 0; ch < 3; ch++) {
			m->ext[i][ch] = c->scattering_per_km[ch] + c->absorption_per_km[ch];
			m->majorant[ch] += m->ext[i][ch] * dmax;
		}
		for (int k = 0; k < 2; k++) {
			const struct atmo_layer *l = &c->density.layers[k];
			if (l->exp_term != 0.0 && l->exp_scale_per_km != 0.0)
				m->dh_max_km = fmin(m->dh_max_km, 2.0 / fabs(l->exp_scale_per_km));
			layer_kinks(m, l, shell);
		}
		add_kink(m, c->density.layers[0].width_km, shell);
	}
	for (int ch = 0; ch < 3; ch++) {
		/* Rounding in atmo_density must never exceed the majorant. */
		m->majorant[ch] *= 1.0 + 1e-9;
		m->albedo[ch] = a->ground_albedo[ch];
		m->illuminance[ch] = sun->illuminance[ch];
	}
	pt_direction(sun->elevation_deg, sun->azimuth_deg, m->sun);
	pt_basis(m->sun, m->sun_u, m->sun_v);
	double half = sun->angular_radius_deg * PI / 360.0;
	m->sun_one_minus_cos = 2.0 * sin(half) * sin(half);
}

/* ---- geometry ---- */

/* |x|^2 - r^2 without cancellation near the sphere. */
static double sphere_c(const double x[3], double r)
{
	double len = sqrt(dot(x, x));
	return (len - r) * (len + r);
}

/* Distance from x (inside the shell) along d to where the ray leaves it;
 * *ret_ground says whether that is the ground. A ray only meets the ground
 * while it goes down, which keeps rays that start on the ground off it. */
double pt_exit_distance(const struct medium *m, const double x[3], const double d[3],
			    int *ret_ground)
{
	double b = dot(x, d);
	if (b < 0.0) {
		double c = sphere_c(x, m->rb);
		if (c <= 0.0) {
			*ret_ground = 1;
			return 0.0;
		}
		double disc = b * b - c;
		if (disc >= 0.0) {
			*ret_ground = 1;
			return c / (-b + sqrt(disc));
		}
	}
	*ret_ground = 0;
	double c = sphere_c(x, m->rt);
	double s = sqrt(fmax(0.0, b * b - c));
	double t = b > 0.0 ? -c / (b + s) : -b + s;
	return t > 0.0 ? t : 0.0;
}

/* The view ray's stretch inside the shell, [*t0, *t1]; 0 if it misses. */
int pt_view_segment(const struct medium *m, const double o[3], const double d[3],
			double *t0, double *t1, int *ret_ground)
{
	*ret_ground = 0;
	if (sqrt(dot(o, o)) <= m->rt) {
		*t0 = 0.0;
		*t1 = pt_exit_distance(m, o, d, ret_ground);
		return *t1 > 0.0 || *ret_ground;
	}
	double b = dot(o, d), c = sphere_c(o, m->rt), disc = b * b - c;
	if (disc <= 0.0 || b >= 0.0)
		return 0;
	double enter = c / (-b + sqrt(disc)), x[3];
	int g;
	axpy(o, enter, d, x);
	double len = pt_exit_distance(m, x, d, &g);
	*t0 = enter;
	*t1 = enter + len;
	*ret_ground = g;
	return 1;
}

/* ---- quadrature cells along a ray ---- */

/* Walks [ta, tb] along o + t d in cells whose ends include the point closest
 * to the centre and the crossings of every kink altitude, each cell short
 * enough in altitude (dh_max, 1 km + 10 % of the altitude) and length
 * (20 km) for 8-point Gauss-Legendre to integrate the profiles to rounding. */
void pt_walk_init(struct walk *w, const struct medium *m, const double o[3],
		      const double d[3], double ta, double tb)
{
	w->m = m;
	w->o = o;
	w->d = d;
	w->nbp = 0;
	w->bp[w->nbp++] = ta;
	double tc = -dot(o, d);
	if (tc > ta && tc < tb)
		w->bp[w->nbp++] = tc;
	for (int k = 0; k < m->n_kinks && w->nbp < MAX_BREAKS - 3; k++) {
		double r = m->rb + m->kink_km[k], b = dot(o, d), c = sphere_c(o, r);
		double disc = b * b - c;
		if (disc <= 0.0)
			continue;
		double s = sqrt(disc);
		double roots[2] = { -b - s, -b + s };
		for (int i = 0; i < 2; i++)
			if (roots[i] > ta && roots[i] < tb)
				w->bp[w->nbp++] = roots[i];
	}
	w->bp[w->nbp++] = tb;
	for (int i = 1; i < w->nbp; i++)	/* insertion sort: a few entries */
		for (int k = i; k > 0 && w->bp[k] < w->bp[k - 1]; k--) {
			double tmp = w->bp[k];
			w->bp[k] = w->bp[k - 1];
			w->bp[k - 1] = tmp;
		}
	w->j = 0;
	w->t = ta;
}

int pt_walk_next(struct walk *w, double *ret_a, double *ret_b)
{
	while (w->j + 1 < w->nbp && w->t >= w->bp[w->j + 1])
		w->j++;
	if (w->j + 1 >= w->nbp)
		return 0;
	double x[3];
	axpy(w->o, w->t, w->d, x);
	double r = sqrt(dot(x, x)), h = r - w->m->rb;
	double mu = fabs(dot(x, w->d)) / r;
	double dh = fmin(1.0 + 0.1 * fmax(h, 0.0), w->m->dh_max_km);
	double step = mu > 0.0 ? fmin(20.0, dh / mu) : 20.0;
	double end = w->bp[w->j + 1];
	/* Avoid a sliver cell at the end of a piece. */
	double b = w->t + step > end - 0.25 * step ? end : w->t + step;
	*ret_a = w->t;
	*ret_b = b;
	w->t = b;
	return 1;
}

/* Optical depth per channel of the cell [a, b] along o + t d. */
void pt_cell_tau(const struct medium *m, const double o[3], const double d[3],
		     double a, double b, double ret[3])
{
	double mid = 0.5 * (a + b), half = 0.5 * (b - a), x[3];
	double rho[ATMO_MAX_CONSTITUENTS];
	ret[0] = ret[1] = ret[2] = 0.0;
	for (int k = 0; k < 8; k++) {
		double t = mid + (k < 4 ? -pt_gl_x[k] : pt_gl_x[k - 4]) * half;
		double w = pt_gl_w[k & 3] * half;
		axpy(o, t, d, x);
		air_densities(m, x, rho);
		for (int i = 0; i < m->n; i++)
			for (int ch = 0; ch < 3; ch++)
				ret[ch] += w * m->ext[i][ch] * rho[i];
	}
}

/* Optical depth along the whole ray [ta, tb]. */
void pt_ray_tau(const struct medium *m, const double o[3], const double d[3],
		    double ta, double tb, double ret[3])
{
	struct walk w;
	double a, b, c[3];
	ret[0] = ret[1] = ret[2] = 0.0;
	pt_walk_init(&w, m, o, d, ta, tb);
	while (pt_walk_next(&w, &a, &b)) {
		pt_cell_tau(m, o, d, a, b, c);
		for (int ch = 0; ch < 3; ch++)
			ret[ch] += c[ch];
	}
}

int pt_check_args(const struct atmo *a, const struct pt_sun *sun)
{
	char err[256];
	if (!a || !sun || atmo_validate(a, err, sizeof(err)) < 0)
		return -EINVAL;
	if (!(sun->angular_radius_deg > 0.0 && sun->angular_radius_deg < 90.0) ||
	    !isfinite(sun->elevation_deg) || !isfinite(sun->azimuth_deg))
		return -EINVAL;
	for (int ch = 0; ch < 3; ch++)
		if (!isfinite(sun->illuminance[ch]) || sun->illuminance[ch] < 0.0)
			return -EINVAL;
	return 0;
}


/* ---- the scene: clouds and terrain ---- */

int pt_medium_scene(struct medium *m, const struct pt_scene *scene)
{
	if (!scene)
		return 0;
	if (scene->n_layers < 0 || scene->n_layers > SKYCLOUD_MAX_LAYERS ||
	    (scene->view != PT_VIEW_AIR && scene->view != PT_VIEW_ALL))
		return -EINVAL;
	m->n_layers = scene->n_layers;
	for (int i = 0; i < m->n_layers; i++) {
		const struct skycloudd_layer *L = &scene->layers[i];
		if (L->type < 0 || L->type >= SKYCLOUD_N_TYPES || !(L->top_km > L->base_km))
			return -EINVAL;
		m->layers[i] = *L;
		m->layer_albedo[i] = skycloud_types[L->type].albedo;
		m->layer_g[i] = skycloud_types[L->type].phase_g;
	}
	m->offset_km[0] = scene->offset_km[0];
	m->offset_km[1] = scene->offset_km[1];
	const struct skyterrain *t = scene->terrain;
	m->has_terrain = t && t->texels && t->extent_km > 0.0 && t->max_texel > 0 &&
			 t->height_km > 0.0;
	if (m->has_terrain)
		m->terrain = *t;
	m->view = scene->view;
	return 0;
}

int pt_terrain_hit(const struct medium *m, const double x[3], const double d[3], double t_max,
		   double *ret_t)
{
	const double q[3] = { x[0], x[1], x[2] - m->rb };

	return m->has_terrain && skyterraind_ray_hit(&m->terrain, m->rb, q, d, t_max, ret_t);
}

/* The vertical at x, the terrain's slope laid on it along the local east
 * and north. */
void pt_terrain_normal(const struct medium *m, const double x[3], double ret_n[3])
{
	double g[2], up[3], len = sqrt(dot(x, x));
	double e[3] = { 1, 0, 0 }, nn[3] = { 0, 1, 0 };

	skyterraind_height_grad_km(&m->terrain, x[0], x[1], g);
	for (int i = 0; i < 3; i++)
		up[i] = x[i] / len;
	for (int i = 0; i < 3; i++) {
		e[i] -= up[i] * up[0];
		nn[i] -= up[i] * up[1];
	}
	double le = sqrt(dot(e, e)), ln = sqrt(dot(nn, nn));
	for (int i = 0; i < 3; i++)
		ret_n[i] = up[i] - g[0] * e[i] / le - g[1] * nn[i] / ln;
	double l = sqrt(dot(ret_n, ret_n));
	for (int i = 0; i < 3; i++)
		ret_n[i] /= l;
}

double pt_cloud_tau(const struct medium *m, const double x[3], const double d[3], double t_max,
		    int steps)
{
	const double q[3] = { x[0], x[1], x[2] - m->rb };

	if (!m->n_layers)
		return 0.0;
	return skycloudd_optical_depth(m->layers, m->n_layers, m->offset_km, m->rb, q, d, t_max,
				       steps);
}

/* The majorant along a ray, piecewise constant: the air's everywhere, plus
 * each layer's extinction inside its shell, widened by SHELL_SLACK_KM so
 * that rounding at a shell never puts density above it. */
#define SHELL_SLACK_KM 1e-9
#define MAX_SEGS (4 * SKYCLOUD_MAX_LAYERS + 1)
struct segs {
	int n;
	double t[MAX_SEGS + 1];
	double maj[MAX_SEGS];
};

static void add_crossings(const struct medium *m, const double x[3], const double d[3], double r,
			  double te, double *bp, int *nb)
{
	double b = dot(x, d), c = sphere_c(x, r), disc = b * b - c;

	if (disc <= 0.0)
		return;
	double q = sqrt(disc), roots[2] = { -b - q, -b + q };
	for (int k = 0; k < 2; k++)
		if (roots[k] > 0.0 && roots[k] < te)
			bp[(*nb)++] = roots[k];
}

static void segments(const struct medium *m, const double x[3], const double d[3], double te,
		     int ch, struct segs *s)
{
	double bp[MAX_SEGS + 1];
	int nb = 0;

	bp[nb++] = 0.0;
	for (int i = 0; i < m->n_layers; i++) {
		if (!(m->layers[i].cover > 0.0))
			continue;
		add_crossings(m, x, d, m->rb + m->layers[i].base_km - SHELL_SLACK_KM, te, bp, &nb);
		add_crossings(m, x, d, m->rb + m->layers[i].top_km + SHELL_SLACK_KM, te, bp, &nb);
	}
	bp[nb++] = te;
	for (int i = 1; i < nb; i++)	/* insertion sort: a few entries */
		for (int k = i; k > 0 && bp[k] < bp[k - 1]; k--) {
			double tmp = bp[k];
			bp[k] = bp[k - 1];
			bp[k - 1] = tmp;
		}
	s->n = 0;
	s->t[0] = 0.0;
	for (int k = 0; k + 1 < nb; k++) {
		if (!(bp[k + 1] > bp[k]))
			continue;
		double p[3], maj = m->majorant[ch];
		axpy(x, 0.5 * (bp[k] + bp[k + 1]), d, p);
		double h = pt_altitude(m, p);
		for (int i = 0; i < m->n_layers; i++)
			if (m->layers[i].cover > 0.0 && h > m->layers[i].base_km - SHELL_SLACK_KM &&
			    h < m->layers[i].top_km + SHELL_SLACK_KM)
				maj += m->layers[i].extinction_per_km;
		s->maj[s->n] = maj;
		s->t[++s->n] = bp[k + 1];
	}
}

double pt_transmittance(const struct medium *m, const double x[3], const double d[3], int ch,
			struct rng *r)
{
	int ground;
	double te = pt_exit_distance(m, x, d, &ground), th, p[3], T = 1.0;
	struct segs s;

	if (ground || pt_terrain_hit(m, x, d, te, &th))
		return 0.0;
	segments(m, x, d, te, ch, &s);
	for (int k = 0; k < s.n; k++) {
		double maj = s.maj[k], t = s.t[k];
		if (maj <= 0.0)
			continue;
		for (;;) {
			t -= log1p(-rnd(r)) / maj;
			if (t >= s.t[k + 1])
				break;
			axpy(x, t, d, p);
			T *= 1.0 - extinction(m, p, ch) / maj;
			if (T < 1e-3) {
				/* Roulette: a dim shadow ray is not worth finishing. */
				if (rnd(r) >= 0.25)
					return 0.0;
				T *= 4.0;
			}
		}
	}
	return T;
}

/* A point of the terrain met at p, moved out along its normal until it is
 * clear of it (a path leaves from there). */
static void terrain_vertex(const struct medium *m, const double p[3], double ret_x[3],
			   double ret_n[3])
{
	pt_terrain_normal(m, p, ret_n);
	for (double eps = 1e-6;; eps *= 2.0) {
		axpy(p, eps, ret_n, ret_x);
		double q[3] = { ret_x[0], ret_x[1], ret_x[2] - m->rb };
		if (skyterraind_clearance_km(&m->terrain, m->rb, q) > 0.0 || eps > 1e-2)
			return;
	}
}

enum pt_event pt_fly(const struct medium *m, const double x[3], const double d[3], int ch,
		     struct rng *r, struct pt_hit *ret)
{
	int ground, terrain = 0;
	double te = pt_exit_distance(m, x, d, &ground), th;
	struct segs s;

	if (pt_terrain_hit(m, x, d, te, &th)) {
		te = th;
		terrain = 1;
	}
	segments(m, x, d, te, ch, &s);
	for (int k = 0; k < s.n; k++) {
		double maj = s.maj[k], t = s.t[k];
		if (maj <= 0.0)
			continue;
		for (;;) {
			t -= log1p(-rnd(r)) / maj;
			if (t >= s.t[k + 1])
				break;
			axpy(x, t, d, ret->p);
			pt_densities(m, ret->p, ret->rho);
			double st = pt_sigma_t(m, ret->rho, ch);
			if (rnd(r) * maj < st) {
				ret->sigma_t = st;
				return PT_COLLIDE;
			}
		}
	}
	double p[3];
	axpy(x, te, d, p);
	if (terrain) {
		terrain_vertex(m, p, ret->p, ret->normal);
		return PT_SURFACE;
	}
	if (!ground)
		return PT_ESCAPE;
	double k = m->rb / sqrt(dot(p, p));
	for (int i = 0; i < 3; i++) {
		ret->p[i] = p[i] * k;
		ret->normal[i] = ret->p[i] / m->rb;
	}
	return PT_SURFACE;
}
