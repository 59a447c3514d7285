/* pt_render.c - the path tracer's driver: batches of work items over a
 * fixed thread pool, merged in a fixed order so that results do not depend
 * on the threads, until each direction converges; and the tables'
 * approximations traced (pt_render_approx). */
#include "pt_internal.h"

#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <unistd.h>

#define CHUNK 64		/* samples per work item: the unit of determinism */

struct acc {
	uint64_t n;
	double mean[3], m2[3];
};

/* Chan et al.'s pairwise merge of running means and squared deviations. */
static void acc_merge(struct acc *a, const struct acc *b)
{
	if (!b->n)
		return;
	uint64_t n = a->n + b->n;
	for (int ch = 0; ch < 3; ch++) {
		double delta = b->mean[ch] - a->mean[ch];
		a->mean[ch] += delta * (double)b->n / (double)n;
		a->m2[ch] += b->m2[ch] + delta * delta * (double)a->n * (double)b->n / (double)n;
	}
	a->n = n;
}

struct job {
	const struct medium *m;
	const struct atmo *a;
	double altitude_km;
	const struct pt_dir *dirs;
	struct view *views;
	const struct pt_options *opt;
	/* the current batch */
	int phase;		/* 0: build views, 1: trace */
	size_t n_items;
	const size_t *active;	/* direction of each active slot */
	const uint64_t *base;	/* first sample of this batch, per slot */
	uint32_t chunks;	/* per slot */
	struct acc *items;
	atomic_size_t next;
};

static void run_item(struct job *j, size_t item)
{
	if (j->phase == 0) {
		struct view *v = &j->views[item];
		v->err = pt_view_build(v, j->m, j->altitude_km, &j->dirs[item]);
		return;
	}
	size_t slot = item / j->chunks, dir = j->active[slot];
	uint64_t first = j->base[slot] + (uint64_t)(item % j->chunks) * CHUNK;
	struct acc a = { 0 };
	for (uint64_t s = first; s < first + CHUNK; s++) {
		a.n++;
		for (int ch = 0; ch < 3; ch++) {
			struct rng r;
			pt_rng_init(&r, j->opt->seed, dir, s, ch);
			double x = pt_sample_view(j->m, &j->views[dir], j->opt->mode, ch, &r);
			double delta = x - a.mean[ch];
			a.mean[ch] += delta / (double)a.n;
			a.m2[ch] += delta * (x - a.mean[ch]);
		}
	}
	j->items[item] = a;
}

static void *worker(void *arg)
{
	struct job *j = arg;
	for (;;) {
		size_t item = atomic_fetch_add(&j->next, 1);
		if (item >= j->n_items)
			return NULL;
		run_item(j, item);
	}
}

static int run_parallel(struct job *j, int threads)
{
	pthread_t tid[256];
	int started = 0, r = 0;
	atomic_store(&j->next, 0);
	for (; started < threads - 1 && started < 256; started++) {
		r = pthread_create(&tid[started], NULL, worker, j);
		if (r)
			break;
	}
	worker(j);
	for (int i = 0; i < started; i++)
		pthread_join(tid[i], NULL);
	return -r;
}

void pt_options_default(struct pt_options *ret)
{
	*ret = (struct pt_options){ .mode = PT_SKY, .rel_error = 0.01, .min_samples = 4096,
		.max_samples = 1ull << 24, .batch = 4096, .threads = 0, .seed = 1 };
}

static int converged(const struct acc *a, const struct pt_options *opt)
{
	if (a->n < opt->min_samples || a->n < 2)
		return 0;
	if (a->n >= opt->max_samples)
		return 1;
	if (!(opt->rel_error > 0.0))
		return 0;
	for (int ch = 0; ch < 3; ch++) {
		double se = sqrt(a->m2[ch] / (double)(a->n - 1) / (double)a->n);
		if (a->mean[ch] == 0.0 ? a->m2[ch] != 0.0 : se > opt->rel_error * fabs(a->mean[ch]))
			return 0;
	}
	return 1;
}

/* The flags of render(): struct medium's isotropic and multi_only. */
#define RENDER_ISOTROPIC 1
#define RENDER_MULTI_ONLY 2

static int render(const struct atmo *a, double altitude_km, const struct pt_sun *sun,
		  const struct pt_scene *scene, const struct pt_dir *dirs, size_t n,
		  const struct pt_options *opt, int flags, struct pt_result *ret);

int pt_render(const struct atmo *a, double altitude_km, const struct pt_sun *sun,
	      const struct pt_dir *dirs, size_t n, const struct pt_options *opt,
	      struct pt_result *ret)
{
	return render(a, altitude_km, sun, NULL, dirs, n, opt, 0, ret);
}

int pt_render_scene(const struct atmo *a, double altitude_km, const struct pt_sun *sun,
		    const struct pt_scene *scene, const struct pt_dir *dirs, size_t n,
		    const struct pt_options *opt, struct pt_result *ret)
{
	return render(a, altitude_km, sun, scene, dirs, n, opt, 0, ret);
}

static int render(const struct atmo *a, double altitude_km, const struct pt_sun *sun,
		  const struct pt_scene *scene, const struct pt_dir *dirs, size_t n,
		  const struct pt_options *opt, int flags, struct pt_result *ret)
{
	struct medium m;
	struct job j = { 0 };
	struct acc *accs = NULL;
	size_t *active = NULL;
	uint64_t *base = NULL;
	int r = pt_check_args(a, sun);

	if (r < 0 || !opt || (n && (!dirs || !ret)) || !isfinite(altitude_km) ||
	    !opt->max_samples || opt->mode < PT_SKY || opt->mode > PT_GROUND)
		return -EINVAL;
	if (!n)
		return 0;
	pt_medium_init(&m, a, sun);
	if (pt_medium_scene(&m, scene) < 0)
		return -EINVAL;
	m.isotropic = !!(flags & RENDER_ISOTROPIC);
	m.multi_only = !!(flags & RENDER_MULTI_ONLY);
	int threads = opt->threads > 0 ? opt->threads : (int)sysconf(_SC_NPROCESSORS_ONLN);
	if (threads < 1)
		threads = 1;
	uint32_t chunks = (opt->batch + CHUNK - 1) / CHUNK;
	if (!chunks)
		chunks = 1;

	j.m = &m;
	j.a = a;
	j.altitude_km = altitude_km;
	j.dirs = dirs;
	j.opt = opt;
	j.chunks = chunks;
	j.views = calloc(n, sizeof(*j.views));
	accs = calloc(n, sizeof(*accs));
	active = calloc(n, sizeof(*active));
	base = calloc(n, sizeof(*base));
	j.items = calloc(n * chunks, sizeof(*j.items));
	if (!j.views || !accs || !active || !base || !j.items) {
		r = -ENOMEM;
		goto out;
	}

	j.phase = 0;
	j.n_items = n;
	r = run_parallel(&j, threads);
	for (size_t i = 0; i < n && r == 0; i++)
		r = j.views[i].err;
	if (r < 0)
		goto out;

	j.phase = 1;
	j.active = active;
	j.base = base;
	for (;;) {
		size_t n_active = 0;
		for (size_t i = 0; i < n; i++)
			if (!converged(&accs[i], opt)) {
				active[n_active] = i;
				base[n_active] = accs[i].n;
				n_active++;
			}
		if (!n_active)
			break;
		j.n_items = n_active * chunks;
		r = run_parallel(&j, threads);
		if (r < 0)
			goto out;
		/* Merge in item order: the sums do not depend on the threads. */
		for (size_t it = 0; it < j.n_items; it++)
			acc_merge(&accs[active[it / chunks]], &j.items[it]);
	}
	for (size_t i = 0; i < n; i++) {
		ret[i].samples = accs[i].n;
		for (int ch = 0; ch < 3; ch++) {
			ret[i].radiance[ch] = accs[i].mean[ch];
			ret[i].std_error[ch] = accs[i].n > 1 ?
				sqrt(accs[i].m2[ch] / (double)(accs[i].n - 1) / (double)accs[i].n) : 0.0;
		}
	}
	r = 0;
out:
	if (j.views)
		for (size_t i = 0; i < n; i++)
			pt_view_free(&j.views[i]);
	free(j.views);
	free(j.items);
	free(accs);
	free(active);
	free(base);
	return r;
}

/* ---- the tables' approximations, traced ---- */

/* ret += sign * part, standard errors in quadrature. */
static void add_parts(struct pt_result *ret, const struct pt_result *part, size_t n, double sign)
{
	for (size_t i = 0; i < n; i++) {
		ret[i].samples += part[i].samples;
		for (int ch = 0; ch < 3; ch++) {
			ret[i].radiance[ch] += sign * part[i].radiance[ch];
			ret[i].std_error[ch] = hypot(ret[i].std_error[ch], part[i].std_error[ch]);
		}
	}
}

/* Delta-M with the TMS correction (Wiscombe 1977; Nakajima and Tanaka
 * 1988): the first order exactly, in the real medium, plus every higher
 * order of the scaled medium, in which the constituent's forward peak f is
 * no scattering at all (sigma_s' = (1 - f) sigma_s, extinction less f
 * sigma_s, a Henyey-Greenstein phase of g'). The two parts are traced
 * separately, so their standard errors add in quadrature. TMS loses the
 * light that the peak scatters and the rest of the phase scatters once
 * toward the eye (the scaled medium counts it as single scattering of its
 * stronger direct beam); ap->delta_excess keeps it: plus the scaled
 * medium's first order, minus the same through the real transmittances. */
static int render_delta_m(const struct atmo *a, double altitude_km, const struct pt_sun *sun,
			  const struct pt_dir *dirs, size_t n, const struct pt_options *opt,
			  const struct pt_approx *ap, struct pt_result *ret)
{
	struct atmo scaled = *a;
	struct pt_options single = *opt, multi = *opt;
	struct pt_result *part;
	int k = ap->delta_m - 1, r;

	if (k >= a->n_constituents || !(ap->delta_f >= 0.0 && ap->delta_f < 1.0) ||
	    !(fabs(ap->delta_g) < 1.0))
		return -EINVAL;
	for (int ch = 0; ch < 3; ch++)
		scaled.c[k].scattering_per_km[ch] *= 1.0 - ap->delta_f;
	scaled.c[k].phase = ATMO_PHASE_HENYEY_GREENSTEIN;
	scaled.c[k].g = ap->delta_g;
	part = calloc(n ? n : 1, sizeof(*part));
	if (!part)
		return -ENOMEM;
	single.mode = PT_SINGLE;
	multi.mode = PT_SKY;
	r = render(a, altitude_km, sun, NULL, dirs, n, &single, 0, ret);
	if (r == 0)
		r = render(&scaled, altitude_km, sun, NULL, dirs, n, &multi,
			   (ap->delta_excess ? 0 : RENDER_MULTI_ONLY) | (ap->isotropic ? RENDER_ISOTROPIC : 0),
			   part);
	add_parts(ret, part, n, 1.0);
	if (r == 0 && ap->delta_excess) {
		/* The scaled medium's first order through the real medium's
		 * transmittances: the removed scattering f sigma_s becomes
		 * absorption, so extinction is the real one. */
		struct atmo absorbing = scaled;
		for (int ch = 0; ch < 3; ch++)
			absorbing.c[k].absorption_per_km[ch] += ap->delta_f * a->c[k].scattering_per_km[ch];
		r = render(&absorbing, altitude_km, sun, NULL, dirs, n, &single, 0, part);
		add_parts(ret, part, n, -1.0);
	}
	free(part);
	return r;
}

int pt_render_approx(const struct atmo *a, double altitude_km, const struct pt_sun *sun,
		     const struct pt_dir *dirs, size_t n, const struct pt_options *opt,
		     const struct pt_approx *ap, struct pt_result *ret)
{
	if (!ap || ap->delta_m < 0 || !opt || opt->mode != PT_SKY)
		return -EINVAL;
	if (ap->delta_m > 0)
		return render_delta_m(a, altitude_km, sun, dirs, n, opt, ap, ret);
	return render(a, altitude_km, sun, NULL, dirs, n, opt, ap->isotropic ? RENDER_ISOTROPIC : 0, ret);
}
