/* model_ms.c - the reference model's multi-scattering table: each texel's
 * directions, the shape of the multiply scattered light, and the
 * neighbourhood iteration. */
#include "model_internal.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

/* Sub-samples per axis of a direction's cell for its mean phase. */
#define MS_PHASE_SUB 2
/* The 64-direction grid: rings of cos-zenith, denser near the horizon, by
 * azimuth columns (why 16 x 4 and these rings: multiscatter.comp). */
#define MS_RINGS 16
#define MS_COLS 4
#define MS_RING_POW 1.2
/* The weights of A, the ground's share of psi (see msgrid.glsl). */
#define SHARE_LUM v(0.2126, 0.7152, 0.0722)

/* The cosine of ring edge e (0: zenith, MS_RINGS: nadir); for two
 * directions, the hemispheres' edges (1, 0, -1). */
static double ms_ring_edge(uint32_t e, uint32_t n)
{
	if (n == 2)
		return 1.0 - e;
	double s = 1.0 - 2.0 * e / MS_RINGS;
	return (s < 0 ? -1.0 : 1.0) * pow(fabs(s), MS_RING_POW);
}

/* Direction k's ring's top and bottom cosines. */
static void ms_ring(uint32_t k, uint32_t n, double *ret_top, double *ret_bot)
{
	uint32_t ring = n == 2 ? k : k / MS_COLS;
	*ret_top = ms_ring_edge(ring, n);
	*ret_bot = ms_ring_edge(ring + 1, n);
}

/* Direction k's cell's solid angle over the mean cell's. */
static double ms_cell_weight(uint32_t k, uint32_t n)
{
	double top, bot;
	ms_ring(k, n, &top, &bot);
	return n == 2 ? 1.0 : (top - bot) * MS_RINGS * 0.5;
}

/* The mean over direction k's cell of constituent kc's phase toward the sun,
 * from MS_PHASE_SUB^2 equal-area sub-samples (see multiscatter.comp). The
 * cells: MS_RINGS rings (ms_ring_edge()) by MS_COLS azimuth columns, or for
 * two directions the upper and lower hemispheres. With ret_xy2, also the
 * sub-samples' mean x^2 - y^2 weighted by the phase (cell_xy2 in
 * multiscatter.comp). */
static double ms_cell_phase(const struct atmo_constituent *kc, uint32_t k, uint32_t n, v3 sun, double *ret_xy2)
{
	uint32_t col = n == 2 ? 0 : k % MS_COLS;
	double dphi = n == 2 ? 2.0 * SKYMAP_PI : 2.0 * SKYMAP_PI / MS_COLS, sum = 0, xy2 = 0, top, bot;
	ms_ring(k, n, &top, &bot);
	for (int a = 0; a < MS_PHASE_SUB; a++) {
		double ct = top + (bot - top) * (a + 0.5) / MS_PHASE_SUB;
		double st = skymap_safe_sqrt(1.0 - ct * ct);
		for (int b = 0; b < MS_PHASE_SUB; b++) {
			double ph = dphi * (col + (b + 0.5) / MS_PHASE_SUB);
			double p = phase_value(kc->phase, kc->g, st * cos(ph) * sun.x + ct * sun.z);
			sum += p;
			xy2 += p * st * st * cos(2.0 * ph);
		}
	}
	if (ret_xy2)
		*ret_xy2 = xy2 / fmax(sum, 1e-30);
	return sum / (MS_PHASE_SUB * MS_PHASE_SUB);
}

static v3 ms_direction(uint32_t k, uint32_t n)
{
	if (n == 2)
		return v(0, 0, k == 0 ? 1.0 : -1.0);
	double top, bot;
	ms_ring(k, n, &top, &bot);
	double ct = 0.5 * (top + bot);
	double ph = 2.0 * SKYMAP_PI * ((k % MS_COLS) + 0.5) / MS_COLS;
	double st = skymap_safe_sqrt(1.0 - ct * ct);
	return v(st * cos(ph), st * sin(ph), ct);
}

/* psi again with the higher orders' transfer f_eff = f + 5 g2 <P2> <f P2>
 * (multiscatter.comp's main): under a Rayleigh lobe, where the sun is up,
 * light scattered from a field brighter toward the horizon goes on more
 * along the long horizontal paths. l2_lum and s2_zz: L2's luminance and zz
 * moment sums; sf, sfzz: the transfer's sums. */
static v3 band2_psi(const struct ctx *c, double h, double mu_s, uint32_t dirs, v3 sl, v3 se, v3 psi,
		    double l2_lum, double s2_zz, v3 sf, v3 sfzz)
{
	double field = fmax(l2_lum + dot(mul(psi, sf), SHARE_LUM), 1e-30);
	double p2 = 1.5 * (s2_zz + dot(mul(psi, sfzz), SHARE_LUM)) / field - 0.5;
	double lit = model_light_visible(c, h, mu_s, c->s->sun.angular_radius_deg * SKYMAP_PI / 180.0);
	v3 s0 = { 0 }, s2 = { 0 };
	for (int n = 0; n < c->a->n_constituents; n++) {
		const struct atmo_constituent *k = &c->a->c[n];
		v3 sig = scale(v(k->scattering_per_km[0], k->scattering_per_km[1], k->scattering_per_km[2]),
			       atmo_density(&k->density, h));
		s0 = add(s0, sig);
		s2 = add(s2, scale(sig, c->lobe_weight[n] * c->lobe_g[1]));
	}
	double e[3], out[3];
	const double f0[3] = { sf.x, sf.y, sf.z }, fzz[3] = { sfzz.x, sfzz.y, sfzz.z };
	const double g0[3] = { s0.x, s0.y, s0.z }, g2[3] = { s2.x, s2.y, s2.z };
	const double l[3] = { sl.x, sl.y, sl.z }, esc[3] = { se.x, se.y, se.z };
	for (int ch = 0; ch < 3; ch++) {
		double fp2 = (1.5 * fzz[ch] - 0.5 * f0[ch]) / dirs;
		e[ch] = esc[ch] - 5.0 * g2[ch] / fmax(g0[ch], 1e-30) * p2 * fp2 * lit;
		out[ch] = l[ch] / fmax(e[ch], 1e-6);
	}
	return v(out[0], out[1], out[2]);
}

/* One texel of the multi-scattering table at altitude h and sun cosine
 * mu_s: psi, the ground's share of it (A) and the escape 1 - f_ms. */
static void ms_texel(const struct ctx *c, uint32_t steps, uint32_t dirs, double h, double mu_s,
		     v3 *ret_psi, double *ret_share, v3 *ret_escape, double ret_shape[4])
{
	const double albedo[3] = { c->a->ground_albedo[0], c->a->ground_albedo[1], c->a->ground_albedo[2] };
	v3 sun = v(skymap_safe_sqrt(1.0 - mu_s * mu_s), 0, mu_s);
	/* s2: L2's second moments zz, xz and, from the sub-samples, xx - yy. */
	v3 sl = { 0 }, sg = { 0 }, sr = { 0 }, se = { 0 }, sm = { 0 }, s2 = { 0 };
	/* Each direction's scattering transfer and its zz and xz moments, per
	 * channel: the higher orders' shape for Rayleigh's band 2. */
	v3 sf = { 0 }, sfzz = { 0 }, sfxz = { 0 };
	double r0 = c->rb + h;
	/* The first scattering of L2 with each constituent's own phase,
	 * the cells' means normalised to sum to exactly 1 over the
	 * sphere (see multiscatter.comp). */
	double norm_phase[ATMO_MAX_CONSTITUENTS] = { 0 };
	for (int n = 0; n < c->a->n_constituents; n++) {
		const struct atmo_constituent *kc = &c->a->c[n];
		if (kc->phase == ATMO_PHASE_NONE)
			continue;
		double sum = 0;
		for (uint32_t k = 0; k < dirs; k++)
			sum += ms_cell_weight(k, dirs) * ms_cell_phase(kc, k, dirs, sun, NULL);
		norm_phase[n] = 1.0 / (4.0 * SKYMAP_PI * sum / dirs);
	}
	for (uint32_t k = 0; k < dirs; k++) {
		v3 dir = ms_direction(k, dirs);
		double cell_phase[ATMO_MAX_CONSTITUENTS] = { 0 }, cell_xy2 = 0;
		for (int n = 0; n < c->a->n_constituents; n++)
			if (c->a->c[n].phase != ATMO_PHASE_NONE)
				cell_phase[n] = ms_cell_phase(&c->a->c[n], k, dirs, sun,
							      n == c->lobe && c->delta >= 0 ? &cell_xy2 : NULL) *
					norm_phase[n];
		double tg, t_end = distance_to_top(c, h, dir.z);
		bool ground = hits_ground(c, h, dir.z, &tg);
		if (ground)
			t_end = tg;
		double dt = t_end / steps;
		v3 tau = { 0 }, l2 = { 0 }, absorbed = { 0 }, transfer = { 0 };
		for (uint32_t s = 0; s < steps; s++) {
			double t = (s + 0.5) * dt, rr;
			double hs = altitude_along(c, h, dir.z, t, &rr);
			struct medium m = model_medium(c, hs);
			v3 w = mul(vexp_neg(tau), segment_weight(m.extinction, dt));
			v3 p = v(dir.x * t / rr, dir.y * t / rr, (r0 + dir.z * t) / rr);
			v3 t_sun = model_light_transmittance(c, hs, dot(p, sun),
						       c->s->sun.angular_radius_deg * SKYMAP_PI / 180.0);
			if (c->delta_light)
				t_sun = model_delta_light_transmittance(c, hs, dot(p, sun),
								  c->s->sun.angular_radius_deg * SKYMAP_PI / 180.0);
			v3 phased = { 0 };
			for (int n = 0; n < c->a->n_constituents; n++) {
				const struct atmo_constituent *kc = &c->a->c[n];
				phased = add(phased, scale(v(kc->scattering_per_km[0], kc->scattering_per_km[1],
							     kc->scattering_per_km[2]),
							   atmo_density(&kc->density, hs) * cell_phase[n]));
			}
			l2 = add(l2, mul(mul(w, phased), t_sun));
			absorbed = add(absorbed, mul(w, m.absorption));
			transfer = add(transfer, mul(w, m.scattering));
			tau = add(tau, scale(m.extinction, dt));
		}
		/* The cell's solid angle over the mean cell's: every
		 * term below is linear in these four. */
		double wk = ms_cell_weight(k, dirs);
		l2 = scale(l2, wk);
		absorbed = scale(absorbed, wk);
		transfer = scale(transfer, wk);
		sf = add(sf, transfer);
		sfzz = add(sfzz, scale(transfer, dir.z * dir.z));
		sfxz = add(sfxz, scale(transfer, dir.x * dir.z));
		v3 t_ray = scale(vexp_neg(tau), wk), returned = { 0 };
		if (ground) {
			v3 n = v(dir.x * t_end / c->rb, dir.y * t_end / c->rb, (r0 + dir.z * t_end) / c->rb);
			double mu_g = dot(n, sun);
			double tg_unused;
			v3 g = mul(t_ray, !c->delta_light ? model_transmittance_to_top(c, 0.0, mu_g)
					  : hits_ground(c, 0.0, mu_g, &tg_unused) ? v(0, 0, 0)
					  : model_delta_light_transmittance(c, 0.0, mu_g, 0.0));
			sg = add(sg, scale(mul(g, v(albedo[0], albedo[1], albedo[2])),
					   (mu_g > 0 ? mu_g : 0) / SKYMAP_PI));
			/* Every order bounces off the ground (see multiscatter.comp). */
			returned = mul(t_ray, v(albedo[0], albedo[1], albedo[2]));
		}
		sl = add(sl, l2);
		/* L2's first and second moments, with the cell's weight as l2
		 * has it by now: its light travels along -dir. */
		double l2_lum = dot(l2, SHARE_LUM);
		sm = add(sm, scale(dir, -l2_lum));
		s2 = add(s2, scale(v(dir.z * dir.z, dir.x * dir.z, cell_xy2), l2_lum));
		sr = add(sr, returned);
		se = add(se, add(add(t_ray, scale(returned, -1.0)), absorbed));
	}
	double lum_l2 = dot(sl, SHARE_LUM);
	sl = scale(sl, 1.0 / dirs);
	sg = scale(sg, 1.0 / dirs);
	sr = scale(sr, 1.0 / dirs);
	se = scale(se, 1.0 / dirs);
	/* The ground's first bounce G: its higher orders without the
	 * ground-to-ground return, its share of psi in A (see
	 * multiscatter.comp). */
	sl = add(sl, mul(sg, v(1.0 - sr.x, 1.0 - sr.y, 1.0 - sr.z)));
	v3 psi = v(sl.x / fmax(se.x, 1e-6), sl.y / fmax(se.y, 1e-6), sl.z / fmax(se.z, 1e-6));
	if (c->lobe >= 0 && c->lobe_g[0] == 0.0)
		psi = band2_psi(c, h, mu_s, dirs, sl, se, psi, lum_l2, s2.x, sf, sfzz);
	double share = dot(sg, SHARE_LUM) / fmax(dot(psi, SHARE_LUM), 1e-30);
	*ret_psi = psi;
	*ret_share = skymap_clamp(share, 0.0, 1.0);
	*ret_escape = se;
	if (ret_shape && c->lobe >= 0) {
		/* The shape of multiscatter.comp (sl is L2 + the ground's part
		 * by now: L2 alone is sm's and s2's weight). */
		double l = fmax(lum_l2, 1e-30);
		double k = l / dirs / fmax(dot(se, SHARE_LUM), 1e-6) / fmax(dot(psi, SHARE_LUM), 1e-30);
		double a = skymap_clamp(-(sm.x / l) / fmax(c->lobe_g[0] * sun.x, 1e-3), 0.0, 1.0);
		ret_shape[0] = k * 3.0 * sm.z / l;
		ret_shape[1] = k * (7.5 * s2.x / l - 2.5);
		/* Under delta-M the (T_xx - T_yy) term less the aureole's, whose
		 * own is the lobe term's, in T_xz's place (multiscatter.comp). */
		double g = c->lobe_g[0];
		ret_shape[2] = k * (c->delta >= 0 ? 3.75 * (s2.z / l - a * g * g * sun.x * sun.x) : 15.0 * s2.y / l);
		ret_shape[3] = k * a;
		if (c->lobe_g[0] == 0.0) {
			/* Rayleigh's band 2 from the whole field: L2 plus psi times
			 * each direction's transfer, where the sun is up
			 * (multiscatter.comp's store_shape). */
			double field = fmax(lum_l2 + dot(mul(psi, sf), SHARE_LUM), 1e-30);
			double lit = model_light_visible(c, h, mu_s, c->s->sun.angular_radius_deg * SKYMAP_PI / 180.0);
			double kf = lit * field / dirs / fmax(dot(psi, SHARE_LUM), 1e-30);
			ret_shape[1] = kf * (7.5 * (s2.x + dot(mul(psi, sfzz), SHARE_LUM)) / field - 2.5);
			ret_shape[2] = kf * 15.0 * (s2.y + dot(mul(psi, sfxz), SHARE_LUM)) / field;
			ret_shape[0] = kf * 3.0 * sm.z / l;
			ret_shape[3] = kf * a;
		}
	}
}

/* Row y of the multi-scattering table at mu_s, read at the row's own u as
 * model_multiscatter() does. */
static v3 ms_row_at(const struct ctx *c, int y, double mu_s)
{
	const struct model_tables *m = c->tab;
	uint32_t w = m->w[1], n = m->h[1];
	y = y < 0 ? 0 : y > (int)n - 1 ? (int)n - 1 : y;
	double mh = skymap_horizon_cos(c->rb, (double)y / (n - 1) * c->shell);
	double d = skymap_clamp(mu_s, -1.0, 1.0) - mh;
	double sn = skymap_clamp(d < 0.0 ? d / (1.0 + mh) : d / (1.0 - mh), -1.0, 1.0);
	double a = copysign(sqrt(fabs(sn)), sn);
	return bilinear(m->t[1] + 4 * (size_t)y * w, w, 1, skymap_unit_to_tex(0.5 + 0.5 * a, w), 0.5);
}

/* psi at altitude h and mu_s for the iteration's neighbours: the parabola
 * through the three nearest rows, each read at its own u (see
 * ms_read_quadratic in msiterate.comp). */
static v3 multiscatter_quadratic(const struct ctx *c, double h, double mu_s)
{
	int n = (int)c->tab->h[1];
	if (n < 3) {
		double share, shape[4];
		return model_multiscatter(c, h, mu_s, &share, shape);
	}
	double p = skymap_clamp(h / c->shell, 0.0, 1.0) * (n - 1);
	int i = (int)floor(p + 0.5);
	i = i < 1 ? 1 : i > n - 2 ? n - 2 : i;
	double f = p - i;
	v3 a = ms_row_at(c, i - 1, mu_s), b = ms_row_at(c, i, mu_s), e = ms_row_at(c, i + 1, mu_s);
	v3 r = add(add(b, scale(add(e, scale(a, -1.0)), 0.5 * f)),
		   scale(add(add(e, scale(b, -2.0)), a), 0.5 * f * f));
	return v(fmax(r.x, 0.0), fmax(r.y, 0.0), fmax(r.z, 0.0));
}

/* The sky's light that reaches the ground per unit albedo, from psi at the
 * ground and the sunlight's irradiance over pi (ground_sky in
 * msiterate.comp). */
static v3 ground_sky(v3 albedo, v3 psi_g, v3 sunlit)
{
	v3 s = add(scale(psi_g, 2.0), scale(mul(albedo, sunlit), -1.0));
	return v(fmax(s.x, 0.0) / (1.0 + albedo.x), fmax(s.y, 0.0) / (1.0 + albedo.y),
		 fmax(s.z, 0.0) / (1.0 + albedo.z));
}

/* The steps of the neighbourhood iteration of psi_ms (msiterate.comp):
 * psi'(x) = L2(x) + the light that the air around x, lit by psi at its own
 * altitude and sun angle (the table), and the ground scatter toward x,
 * with the quadrature of the table. l2 holds each texel's L2 (with the
 * ground's first bounce, as the table has it); the ground's share in A
 * keeps the first bounce's luminance as psi grows. */
static int iterate_multiscatter(const struct ctx *c, const struct state_table_quality *q,
				uint32_t dirs, uint32_t steps, const v3 *l2, double *out)
{
	const v3 albedo = v(c->a->ground_albedo[0], c->a->ground_albedo[1], c->a->ground_albedo[2]);
	size_t n = (size_t)q->width * q->height;
	double *next = malloc(4 * n * sizeof(double));
	if (!next)
		return -ENOMEM;
	for (uint32_t it = 0; it < steps; it++) {
		for (uint32_t j = 0; j < q->height; j++)
			for (uint32_t i = 0; i < q->width; i++) {
				double h, mu_s, share, shape[4];
				skymap_multiscatter_inverse(c->rb, c->rt, (i + 0.5) / q->width,
							    (j + 0.5) / q->height, q->width, q->height, &h, &mu_s);
				v3 sun = v(skymap_safe_sqrt(1.0 - mu_s * mu_s), 0, mu_s), g = { 0 }, first = { 0 };
				v3 returned = { 0 };
				double r0 = c->rb + h;
				for (uint32_t k = 0; k < dirs; k++) {
					v3 dir = ms_direction(k, dirs), gk = { 0 };
					double tg, t_end = distance_to_top(c, h, dir.z);
					bool ground = hits_ground(c, h, dir.z, &tg);
					if (ground)
						t_end = tg;
					double dt = t_end / q->steps;
					v3 tau = { 0 };
					for (uint32_t s = 0; s < q->steps; s++) {
						double t = (s + 0.5) * dt, rr;
						double hs = altitude_along(c, h, dir.z, t, &rr);
						struct medium m = model_medium(c, hs);
						v3 w = mul(vexp_neg(tau), segment_weight(m.extinction, dt));
						v3 p = v(dir.x * t / rr, dir.y * t / rr, (r0 + dir.z * t) / rr);
						gk = add(gk, mul(mul(w, m.scattering), multiscatter_quadratic(c, hs, dot(p, sun))));
						tau = add(tau, scale(m.extinction, dt));
					}
					double wk = ms_cell_weight(k, dirs);
					if (ground) {
						v3 nr = v(dir.x * t_end / c->rb, dir.y * t_end / c->rb,
							  (r0 + dir.z * t_end) / c->rb);
						double mu_g = dot(nr, sun);
						v3 back = mul(vexp_neg(tau), albedo);
						v3 sunlit = scale(model_transmittance_to_top(c, 0.0, mu_g), fmax(mu_g, 0.0) / SKYMAP_PI);
						v3 psi_g = model_multiscatter(c, 0.0, mu_g, &share, shape);
						first = add(first, scale(mul(back, sunlit), wk));
						returned = add(returned, scale(back, wk));
						gk = add(gk, mul(back, ground_sky(albedo, psi_g, sunlit)));
					}
					g = add(g, scale(gk, wk));
				}
				size_t at = (size_t)j * q->width + i;
				const double *own = out + 4 * at;
				/* l2 holds L2 + G (1 - f_ground) as the table had it; here G
				 * counts whole (see msiterate.comp). */
				v3 l2_whole = add(l2[at], scale(mul(first, returned), 1.0 / ((double)dirs * dirs)));
				v3 psi = add(l2_whole, scale(g, 1.0 / dirs));
				double kept = dot(v(own[0], own[1], own[2]), SHARE_LUM) / fmax(dot(psi, SHARE_LUM), 1e-30);
				put(next + 4 * at, psi, skymap_clamp(own[3] * kept, 0.0, 1.0));
				/* The shape, relative to psi, keeps its absolute size as A does. */
				if (c->lobe >= 0)
					for (int k = 0; k < 4; k++)
						c->moment[4 * at + k] *= kept;
			}
		memcpy(out, next, 4 * n * sizeof(double));
	}
	free(next);
	return 0;
}

int model_compute_multiscatter(const struct ctx *c, const struct state_table_quality *q,
			       uint32_t dirs, double *out)
{
	uint32_t steps = state_multiscatter_iterations(c->s);
	/* Delta-M: the table is the scaled medium's (delta_source). */
	struct ctx scaled = *c;
	if (c->delta >= 0) {
		scaled.a = &c->scaled;
		scaled.delta_light = true;
	}
	v3 *l2_of = steps ? calloc((size_t)q->width * q->height, sizeof(v3)) : NULL;
	if (steps && !l2_of)
		return -ENOMEM;
	for (uint32_t j = 0; j < q->height; j++)
		for (uint32_t i = 0; i < q->width; i++) {
			double h, mu_s, share;
			v3 psi, escape;
			skymap_multiscatter_inverse(c->rb, c->rt, (i + 0.5) / q->width, (j + 0.5) / q->height,
						    q->width, q->height, &h, &mu_s);
			ms_texel(&scaled, q->steps, dirs, h, mu_s, &psi, &share, &escape,
				 c->lobe >= 0 ? c->moment + 4 * ((size_t)j * q->width + i) : NULL);
			put(out + 4 * (j * q->width + i), psi, share);
			/* L2 as the iteration recovers it from the table. */
			if (l2_of)
				l2_of[j * q->width + i] = mul(psi, v(fmax(escape.x, 1e-6), fmax(escape.y, 1e-6),
								   fmax(escape.z, 1e-6)));
		}
	int rc = steps ? iterate_multiscatter(c, q, dirs, steps, l2_of, out) : 0;
	free(l2_of);
	return rc;
}

int model_multiscatter_escape(const struct sky_state *s, double altitude_km, double ret_escape[3])
{
	struct model_tables m;
	struct ctx c;
	int rc = model_compute(s, 1u << STATE_TRANSMITTANCE, &m);
	if (rc < 0)
		return rc;
	model_ctx_init(&c, s, &m);
	uint32_t dirs = s->quality.multiscatter_dirs ? s->quality.multiscatter_dirs : 2;
	double share;
	v3 psi, escape;
	ms_texel(&c, s->quality.t[STATE_MULTISCATTER].steps, dirs, altitude_km, 1.0, &psi, &share, &escape, NULL);
	ret_escape[0] = escape.x;
	ret_escape[1] = escape.y;
	ret_escape[2] = escape.z;
	model_tables_finish(&m);
	return 0;
}
