// msiterate.comp - one Jacobi step of the isotropic multiple-scattering
// transfer, psi'(x) = L2(x) + sum over directions of the light psi(y) that
// every point y around x scatters toward x (and the ground returns), with
// psi(y) read from the table at y's own altitude and sun angle.
//
// Hillaire's psi = L2 / (1 - f_ms) assumes that every point around x sees
// the same psi as x. Where the air is optically thick that fails: the
// sunlight dies with depth, so the air above a low point is lit far more
// than the point itself and psi near the ground comes out low (Earth with
// ten times the scattering: the horizon 29 % dark, the day sky 14 %). psi
// depends on altitude and sun angle only (a spherical planet under a
// distant sun), so the table itself tells what every y sees, and a few
// steps of this iteration converge to the transfer's fixed point. The
// engine runs it only for thick atmospheres (state_multiscatter_iterations).
//
// Same directions and steps as multiscatter.comp, so that L2 = psi (1 - f)
// is recovered exactly from the table on the first step (ITER_FIRST),
// which keeps it for the later ones in the scratch buffer.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(constant_id = 16) const int MS_DIRS = 64;
layout(constant_id = 19) const int MS_SUN_GROUP = 4;
layout(constant_id = 21) const bool ITER_FIRST = true;
const int MS_RINGS = 16, MS_COLS = 4, MS_HALF_COLS = MS_COLS / 2;
layout(local_size_x = 8, local_size_y = 8) in;

// The next psi in the table's storage format (copied over the table after
// the pass), then L2 as float32 RGBA per texel.
layout(std430, binding = 9) buffer IterBuf { uint d[]; } IB;

void main()
{
	load_params();
	int x0 = int(gl_GlobalInvocationID.x) * MS_SUN_GROUP, py = int(gl_GlobalInvocationID.y);
	if (x0 >= OUT_W || py >= OUT_H)
		return;

	// The texels' altitude and sun angles, as multiscatter.comp.
	float h = clamp(tex_to_unit((float(py) + 0.5) / float(OUT_H), OUT_H), 0.0, 1.0) * P.planet.z;
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
	mat4x3 scattering_of = mat4x3(0.0), absorption_of = mat4x3(0.0);
	for (int i = 0; i < N_CONST; i++) {
		scattering_of[i] = P.C[i].scattering.rgb;
		absorption_of[i] = P.C[i].absorption.rgb;
	}

	// The light scattered toward x per sun (gathered), and 1 - f as in
	// multiscatter.comp: what leaves or is absorbed.
	vec3 gathered[MS_SUN_GROUP];
	for (int j = 0; j < MS_SUN_GROUP; j++)
		gathered[j] = vec3(0.0);
	vec3 sum_escape = vec3(0.0);
	TAlt ground_alt = t_alt(0.0);
	for (int k = 0; k < n_dirs; k++) {
		vec3 dir;
		if (MS_DIRS == 2) {
			dir = vec3(0.0, 0.0, k == 0 ? 1.0 : -1.0);
		} else {
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
		vec3 tr = vec3(1.0), absorbed = vec3(0.0);
		for (int s = 0; s < STEPS; s++) {
			float t = (float(s) + 0.5) * dt, rr;
			float hs = altitude_along(h, dir.z, t, rr);
			vec4 dens = vec4(0.0);
			for (int i = 0; i < N_CONST; i++)
				dens[i] = density(i, hs);
			vec3 scattering = scattering_of * dens, absorption = absorption_of * dens;
			vec3 step_t, w = tr * step_weight(scattering + absorption, dt, step_t);
			TAlt a = t_alt(hs);
			vec3 up = vec3(dir.xy * t, r0 + dir.z * t) / rr, ws = w * scattering;
			for (int j = 0; j < MS_SUN_GROUP; j++)
				gathered[j] += ws * multiscatter_at(a, dot(up, sun[j]));
			absorbed += w * absorption;
			tr *= step_t;
		}
		vec3 returned = vec3(0.0);
		if (ground && !GROUND_BLACK) {
			// The Lambertian ground under psi sends back albedo times psi.
			vec3 n = vec3(dir.xy * t_end, r0 + dir.z * t_end) / P.planet.x;
			returned = tr * P.albedo.rgb;
			for (int j = 0; j < MS_SUN_GROUP; j++)
				gathered[j] += returned * multiscatter_at(ground_alt, dot(n, sun[j]));
		}
		sum_escape += tr - returned + absorbed;
	}
	vec3 escape = sum_escape * norm;
	int l2_base = (STORAGE_F16 ? 2 : 4) * OUT_W * OUT_H;
	for (int j = 0; j < MS_SUN_GROUP; j++) {
		int i = py * OUT_W + x0 + j;
		if (x0 + j >= OUT_W)
			break;
		vec4 own = texelFetch(MultiscatterTex, i);
		vec3 l2;
		if (ITER_FIRST) {
			// multiscatter.comp stored psi = L2 / max(escape, 1e-6).
			l2 = own.rgb * max(escape, vec3(1e-6));
			for (int c = 0; c < 3; c++)
				IB.d[l2_base + 4 * i + c] = floatBitsToUint(l2[c]);
		} else {
			l2 = vec3(uintBitsToFloat(IB.d[l2_base + 4 * i]), uintBitsToFloat(IB.d[l2_base + 4 * i + 1]),
				  uintBitsToFloat(IB.d[l2_base + 4 * i + 2]));
		}
		STORE_TEXEL(IB, i, vec4(l2 + gathered[j] * norm, own.a));
	}
}
