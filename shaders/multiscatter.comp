// multiscatter.comp - Hillaire's infinite-order isotropic multiple scattering,
// psi_ms = L2 / (1 - f_ms). Directions: 64 on an 8 x 8 equal-area grid, or 2
// (straight up and down).
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
layout(constant_id = 19) const int MS_SUN_GROUP = 4;
layout(local_size_x = 8, local_size_y = 8) in;

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
	const float uniform_phase = 1.0 / (4.0 * PI);
	const int n_dirs = MS_DIRS == 2 ? 2 : 32;
	const float dir_weight = MS_DIRS == 2 ? 1.0 : 2.0;
	float r0 = P.planet.x + h;

	// Per direction: L2 (isotropic phase), f (transfer of unit isotropic
	// light) and the escape 1 - f written as what leaves or is absorbed, so
	// that 1 - f_ms never comes from a cancelling subtraction.
	vec3 sum_l2[MS_SUN_GROUP];
	for (int j = 0; j < MS_SUN_GROUP; j++)
		sum_l2[j] = vec3(0.0);
	vec3 sum_f = vec3(0.0), sum_escape = vec3(0.0);
	for (int k = 0; k < n_dirs; k++) {
		vec3 dir;
		if (MS_DIRS == 2) {
			dir = vec3(0.0, 0.0, k == 0 ? 1.0 : -1.0);
		} else {
			// Ring k / 4, azimuth column k % 4 of 8: phi in (0, pi).
			float ct = 1.0 - 2.0 * (float(k / 4) + 0.5) / 8.0;
			float ph = 2.0 * PI * (float(k % 4) + 0.5) / 8.0;
			float st = safe_sqrt(1.0 - ct * ct);
			dir = vec3(st * cos(ph), st * sin(ph), ct);
		}
		float tg, t_end = distance_to_top(h, dir.z);
		bool ground = hits_ground(h, dir.z, tg);
		if (ground)
			t_end = tg;
		float dt = t_end / float(STEPS);
		vec3 tr = vec3(1.0), f = vec3(0.0), absorbed = vec3(0.0);
		vec3 l2[MS_SUN_GROUP];
		for (int j = 0; j < MS_SUN_GROUP; j++)
			l2[j] = vec3(0.0);
		for (int i = 0; i < STEPS; i++) {
			float t = (float(i) + 0.5) * dt, rr;
			float hs = altitude_along(h, dir.z, t, rr);
			Medium m = medium(hs);
			vec3 step_t, w = tr * step_weight(m.extinction, dt, step_t);
			vec3 ws = w * m.scattering * uniform_phase;
			TAlt a = t_alt(hs);
			vec3 up = vec3(dir.xy * t, r0 + dir.z * t) / rr;
			for (int j = 0; j < MS_SUN_GROUP; j++)
				l2[j] += ws * light_transmittance(a, dot(up, sun[j]), P.sun_dir.w);
			f += w * m.scattering;
			absorbed += w * m.absorption;
			tr *= step_t;
		}
		vec3 returned = vec3(0.0);
		if (ground && !GROUND_BLACK) {
			// Lambertian ground lit by the sun: albedo / pi times the cosine.
			vec3 n = vec3(dir.xy * t_end, r0 + dir.z * t_end) / P.planet.x;
			TAlt a = t_alt(0.0);
			for (int j = 0; j < MS_SUN_GROUP; j++) {
				float mu_g = dot(n, sun[j]);
				l2[j] += tr * transmittance_at(a, mu_g) * max(mu_g, 0.0) * P.albedo.rgb / PI;
			}
			// Under the isotropic field psi the Lambertian ground sends back
			// albedo times psi: a transfer like scattering, so every order
			// bounces off the ground, not only the second.
			returned = tr * P.albedo.rgb;
		}
		for (int j = 0; j < MS_SUN_GROUP; j++)
			sum_l2[j] += l2[j];
		sum_f += f + returned;
		sum_escape += tr - returned + absorbed;
	}
	float norm = dir_weight / float(MS_DIRS);
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
