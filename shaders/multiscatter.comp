// multiscatter.comp - Hillaire's infinite-order isotropic multiple scattering,
// psi_ms = L2 / (1 - f_ms). Directions: 64 on an equal-area grid of 16 rings
// by 4 azimuths, or 2 (straight up and down).
//
// The rays from a point at altitude h do not depend on the sun, so one
// invocation marches them once for MS_SUN_GROUP texels of a row (sun angles)
// and only the light lookups are per texel. The sun lies in the x-z plane,
// so the grid's directions at azimuth phi and -phi contribute alike: half of
// them are marched, counted twice. No shared memory and no barrier: on
// lavapipe a barrier turns every invocation into a coroutine.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(constant_id = 16) const int MS_DIRS = 64;
// Sub-samples per axis of a direction's cell for its mean phase.
const int PHASE_SUB = 2;
// The 64-direction grid: rings of equal cos-zenith height by azimuth
// columns. A ray's path through the shell depends on its zenith angle only,
// and near the horizon that path grows by a factor of ten within a few
// degrees, so the rings carry most of the quadrature's error: 8 rings x 8
// azimuths read the day sky 3 % low and twilight from 10 km 23 % low, 16 x 4
// 2 % and 11 % at the same cost (32 x 2 has too few azimuths for the
// earth's shadow: 32 % low in twilight). skybench accuracy measures it.
const int MS_RINGS = 16, MS_COLS = 4, MS_HALF_COLS = MS_COLS / 2;
layout(constant_id = 19) const int MS_SUN_GROUP = 4;
layout(local_size_x = 8, local_size_y = 8) in;

// Sum of constituent i's phase over the PHASE_SUB^2 equal-area sub-samples
// of marched direction k's cell, toward each sun of the group. Cells: ring
// k / MS_HALF_COLS by azimuth column k % MS_HALF_COLS (of MS_COLS), or for 2
// directions the upper and lower hemispheres.
void cell_phase(int i, int k, vec3 sun[MS_SUN_GROUP], out float ret[MS_SUN_GROUP])
{
	float rings = MS_DIRS == 2 ? 2.0 : float(MS_RINGS);
	float ring = float(MS_DIRS == 2 ? k : k / MS_HALF_COLS);
	float col = float(MS_DIRS == 2 ? 0 : k % MS_HALF_COLS);
	float dphi = MS_DIRS == 2 ? 2.0 * PI : 2.0 * PI / float(MS_COLS);
	int kind = phase_kind(i);
	float g = P.C[i].scattering.w;
	for (int j = 0; j < MS_SUN_GROUP; j++)
		ret[j] = 0.0;
	for (int a = 0; a < PHASE_SUB; a++) {
		float ct = 1.0 - 2.0 * (ring + (float(a) + 0.5) / float(PHASE_SUB)) / rings;
		float st = safe_sqrt(1.0 - ct * ct);
		for (int b = 0; b < PHASE_SUB; b++) {
			float cp = st * cos(dphi * (col + (float(b) + 0.5) / float(PHASE_SUB)));
			for (int j = 0; j < MS_SUN_GROUP; j++)
				ret[j] += phase(kind, g, cp * sun[j].x + ct * sun[j].z);
		}
	}
}

void main()
{
	load_params();
	int x0 = int(gl_GlobalInvocationID.x) * MS_SUN_GROUP, py = int(gl_GlobalInvocationID.y);
	if (x0 >= OUT_W || py >= OUT_H)
		return;

	float h = clamp(tex_to_unit((float(py) + 0.5) / float(OUT_H), OUT_H), 0.0, 1.0) * P.planet.z;
	// skymap.h: u packs texels around the horizon of the altitude.
	float mh = horizon_cos(h);
	vec3 sun[MS_SUN_GROUP];
	for (int j = 0; j < MS_SUN_GROUP; j++) {
		int px = min(x0 + j, OUT_W - 1);
		float a_mu = 2.0 * tex_to_unit((float(px) + 0.5) / float(OUT_W), OUT_W) - 1.0;
		float sn = a_mu * abs(a_mu);
		float mu_s = clamp(mh + sn * (sn < 0.0 ? 1.0 + mh : 1.0 - mh), -1.0, 1.0);
		sun[j] = vec3(safe_sqrt(1.0 - mu_s * mu_s), 0.0, mu_s);
	}
	const int n_dirs = MS_DIRS == 2 ? 2 : 32;
	const float dir_weight = MS_DIRS == 2 ? 1.0 : 2.0;
	const float norm = dir_weight / float(MS_DIRS);
	float r0 = P.planet.x + h;

	// Per direction: L2, f (transfer of unit isotropic light) and the
	// escape 1 - f written as what leaves or is absorbed, so that 1 - f_ms
	// never comes from a cancelling subtraction.
	//
	// L2's first scattering (at y, from the sun toward x) takes each
	// constituent's own phase, not the isotropic one: a forward lobe
	// (g = 0.8 - 0.85) toward a low sun lies along long near-horizontal
	// paths, and the isotropic phase undercounts them. The phase depends on
	// the direction and the sun only, so it is a per-direction weight of
	// each constituent's scattering (q), not a per-step cost. A point value
	// is a poor quadrature of such a lobe over a 0.2 sr cell: q is the
	// cell's mean (PHASE_SUB^2 sub-samples; 2 x 2 reads within 0.1 % of
	// 4 x 4 on Earth, 0.6 % on Mars), normalised so that the cells' phases
	// sum to exactly 1 over the sphere and no energy is made or lost.
	// Only the scattering at x and beyond stays isotropic (Hillaire's
	// assumption).
	// phase_norm: 1 / (4 pi norm sum), over the marched cells, of the
	// sub-sample sums of each constituent's phase, so that the cells'
	// phases integrate to exactly 1 over the sphere.
	float phase_norm[4][MS_SUN_GROUP];
	for (int i = 0; i < N_CONST; i++) {
		if (phase_kind(i) == 0)
			continue;
		float total[MS_SUN_GROUP];
		for (int j = 0; j < MS_SUN_GROUP; j++)
			total[j] = 0.0;
		for (int k = 0; k < n_dirs; k++) {
			float cp[MS_SUN_GROUP];
			cell_phase(i, k, sun, cp);
			for (int j = 0; j < MS_SUN_GROUP; j++)
				total[j] += cp[j];
		}
		for (int j = 0; j < MS_SUN_GROUP; j++)
			phase_norm[i][j] = 1.0 / (4.0 * PI * norm * max(total[j], 1e-30));
	}
	vec3 sum_l2[MS_SUN_GROUP];
	for (int j = 0; j < MS_SUN_GROUP; j++)
		sum_l2[j] = vec3(0.0);
	vec3 sum_f = vec3(0.0), sum_escape = vec3(0.0);
	for (int k = 0; k < n_dirs; k++) {
		vec3 dir;
		if (MS_DIRS == 2) {
			dir = vec3(0.0, 0.0, k == 0 ? 1.0 : -1.0);
		} else {
			// Ring k / MS_HALF_COLS, azimuth column k % MS_HALF_COLS
			// of MS_COLS: phi in (0, pi).
			float ct = 1.0 - 2.0 * (float(k / MS_HALF_COLS) + 0.5) / float(MS_RINGS);
			float ph = 2.0 * PI * (float(k % MS_HALF_COLS) + 0.5) / float(MS_COLS);
			float st = safe_sqrt(1.0 - ct * ct);
			dir = vec3(st * cos(ph), st * sin(ph), ct);
		}
		float tg, t_end = distance_to_top(h, dir.z);
		bool ground = hits_ground(h, dir.z, tg);
		if (ground)
			t_end = tg;
		float dt = t_end / float(STEPS);
		vec3 tr = vec3(1.0), f = vec3(0.0), absorbed = vec3(0.0);
		float q[4][MS_SUN_GROUP];
		for (int i = 0; i < N_CONST; i++) {
			if (phase_kind(i) == 0)
				continue;
			cell_phase(i, k, sun, q[i]);
			for (int j = 0; j < MS_SUN_GROUP; j++)
				q[i][j] *= phase_norm[i][j];
		}
		vec3 l2[MS_SUN_GROUP];
		for (int j = 0; j < MS_SUN_GROUP; j++)
			l2[j] = vec3(0.0);
		for (int s = 0; s < STEPS; s++) {
			float t = (float(s) + 0.5) * dt, rr;
			float hs = altitude_along(h, dir.z, t, rr);
			// medium(), keeping each constituent's scattering.
			vec3 sc[4], scattering = vec3(0.0), absorption = vec3(0.0);
			for (int i = 0; i < N_CONST; i++) {
				float d = density(i, hs);
				sc[i] = d * P.C[i].scattering.rgb;
				scattering += sc[i];
				absorption += d * P.C[i].absorption.rgb;
			}
			vec3 step_t, w = tr * step_weight(scattering + absorption, dt, step_t);
			TAlt a = t_alt(hs);
			vec3 up = vec3(dir.xy * t, r0 + dir.z * t) / rr;
			for (int j = 0; j < MS_SUN_GROUP; j++) {
				vec3 phased = vec3(0.0);
				for (int i = 0; i < N_CONST; i++)
					if (phase_kind(i) != 0)
						phased += sc[i] * q[i][j];
				l2[j] += w * phased * light_transmittance(a, dot(up, sun[j]), P.sun_dir.w);
			}
			f += w * scattering;
			absorbed += w * absorption;
			tr *= step_t;
		}
		for (int j = 0; j < MS_SUN_GROUP; j++)
			sum_l2[j] += l2[j];
		vec3 returned = vec3(0.0);
		if (ground && !GROUND_BLACK) {
			// Lambertian ground lit by the sun: albedo / pi times the cosine.
			vec3 n = vec3(dir.xy * t_end, r0 + dir.z * t_end) / P.planet.x;
			TAlt a = t_alt(0.0);
			for (int j = 0; j < MS_SUN_GROUP; j++) {
				float mu_g = dot(n, sun[j]);
				sum_l2[j] += tr * transmittance_at(a, mu_g) * max(mu_g, 0.0) * P.albedo.rgb / PI;
			}
			// Under the isotropic field psi the Lambertian ground sends back
			// albedo times psi: a transfer like scattering, so every order
			// bounces off the ground, not only the second.
			returned = tr * P.albedo.rgb;
		}
		sum_f += f + returned;
		sum_escape += tr - returned + absorbed;
	}
	vec3 f = sum_f * norm, escape = sum_escape * norm;
	for (int j = 0; j < MS_SUN_GROUP; j++) {
		if (x0 + j >= OUT_W)
			break;
		// Guard: 1 - f_ms is a sum of non-negative terms; the floor of 1e-6
		// only keeps 0 / 0 away (where the escape is 0, L2 is 0 too).
		vec3 psi = sum_l2[j] * norm / max(escape, vec3(1e-6));
		STORE_TEXEL(MB, py * OUT_W + x0 + j, vec4(psi, (f.r + f.g + f.b) / 3.0));
	}
}
