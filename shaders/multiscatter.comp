// multiscatter.comp - Hillaire's infinite-order isotropic multiple scattering,
// psi_ms = L2 / (1 - f_ms): one invocation per texel loops over the
// directions (64 on an 8 x 8 equal-area grid, or 2: straight up and down).
// No shared memory and no barrier: on lavapipe a barrier turns every
// invocation into a coroutine, which costs more than the whole integral.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(constant_id = 16) const int MS_DIRS = 64;
layout(local_size_x = 8, local_size_y = 8) in;

void main()
{
	ivec2 px = ivec2(gl_GlobalInvocationID.xy);
	if (px.x >= OUT_W || px.y >= OUT_H)
		return;

	float h = clamp(tex_to_unit((float(px.y) + 0.5) / float(OUT_H), OUT_H), 0.0, 1.0) * P.planet.z;
	// skymap.h: u packs texels around the horizon of the altitude.
	float a_mu = 2.0 * tex_to_unit((float(px.x) + 0.5) / float(OUT_W), OUT_W) - 1.0;
	float sn = a_mu * abs(a_mu), mh = horizon_cos(h);
	float mu_s = clamp(mh + sn * (sn < 0.0 ? 1.0 + mh : 1.0 - mh), -1.0, 1.0);
	vec3 sun = vec3(safe_sqrt(1.0 - mu_s * mu_s), 0.0, mu_s);
	const float uniform_phase = 1.0 / (4.0 * PI);
	float r0 = P.planet.x + h;

	// Per direction: L2 (isotropic phase), f (transfer of unit isotropic
	// light) and the escape 1 - f written as what leaves or is absorbed, so
	// that 1 - f_ms never comes from a cancelling subtraction.
	vec3 sum_l2 = vec3(0.0), sum_f = vec3(0.0), sum_escape = vec3(0.0);
	for (int k = 0; k < MS_DIRS; k++) {
		vec3 dir;
		if (MS_DIRS == 2) {
			dir = vec3(0.0, 0.0, k == 0 ? 1.0 : -1.0);
		} else {
			float ct = 1.0 - 2.0 * (float(k / 8) + 0.5) / 8.0;
			float ph = 2.0 * PI * (float(k % 8) + 0.5) / 8.0;
			float st = safe_sqrt(1.0 - ct * ct);
			dir = vec3(st * cos(ph), st * sin(ph), ct);
		}
		float tg, t_end = distance_to_top(h, dir.z);
		bool ground = hits_ground(h, dir.z, tg);
		if (ground)
			t_end = tg;
		float dt = t_end / float(STEPS);
		vec3 tau = vec3(0.0), l2 = vec3(0.0), f = vec3(0.0), absorbed = vec3(0.0);
		for (int i = 0; i < STEPS; i++) {
			float t = (float(i) + 0.5) * dt, rr;
			float hs = altitude_along(h, dir.z, t, rr);
			Medium m = medium(hs);
			vec3 w = exp(-tau) * segment_weight(m.extinction, dt);
			float mu_l = dot(vec3(dir.xy * t, r0 + dir.z * t) / rr, sun);
			l2 += w * m.scattering * uniform_phase * transmittance_to_top(hs, mu_l);
			f += w * m.scattering;
			absorbed += w * m.absorption;
			tau += m.extinction * dt;
		}
		vec3 t_ray = exp(-tau), returned = vec3(0.0);
		if (ground && !GROUND_BLACK) {
			// Lambertian ground lit by the sun: albedo / pi times the cosine.
			vec3 n = vec3(dir.xy * t_end, r0 + dir.z * t_end) / P.planet.x;
			float mu_g = dot(n, sun);
			l2 += t_ray * transmittance_to_top(0.0, mu_g) * max(mu_g, 0.0) * P.albedo.rgb / PI;
			// Under the isotropic field psi the Lambertian ground sends back
			// albedo times psi: a transfer like scattering, so every order
			// bounces off the ground, not only the second.
			returned = t_ray * P.albedo.rgb;
		}
		sum_l2 += l2;
		sum_f += f + returned;
		sum_escape += t_ray - returned + absorbed;
	}
	vec3 l2 = sum_l2 / float(MS_DIRS), f = sum_f / float(MS_DIRS);
	vec3 escape = sum_escape / float(MS_DIRS);
	// Guard: 1 - f_ms is a sum of non-negative terms; the floor of 1e-6 only
	// keeps 0 / 0 away (where the escape is 0, L2 is 0 too).
	vec3 psi = l2 / max(escape, vec3(1e-6));
	STORE_TEXEL(MB, px.y * OUT_W + px.x, vec4(psi, (f.r + f.g + f.b) / 3.0));
}
