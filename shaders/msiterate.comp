// msiterate.comp - one Jacobi step of the isotropic multiple-scattering
// transfer, psi'(x) = L2(x) + sum over directions of the light psi(y) that
// every point y around x scatters toward x (and the ground returns), with
// psi(y) read from the table at y's own altitude and sun angle.
//
// Hillaire's psi = L2 / (1 - f_ms) assumes that every point around x sees
// the same psi as x. Where the air is optically thick that fails: the
// sunlight dies with depth, so the air above a low point is lit far more
// than the point itself and psi near the ground comes out low. psi
// depends on altitude and sun angle only (a spherical planet under a
// distant sun), so the table itself tells what every y sees, and a few
// steps of this iteration converge to the transfer's fixed point. The
// engine runs it only for thick atmospheres (state_multiscatter_iterations).
//
// Same directions (msgrid.glsl) and steps as multiscatter.comp, so that
// L2 = psi (1 - f) is recovered exactly from the table on the first step
// (ITER_FIRST), which keeps it for the later ones in the scratch buffer;
// L2 here includes the ground's first bounce as the table has it. The
// grain is multiscatter.comp's: every cell in turn for MS_SUN_GROUP
// texels, or a lane per cell of one texel (MS_LANES > 1).
#version 450
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"
#include "msgrid.glsl"

layout(constant_id = SPEC_ITER_FIRST) const bool ITER_FIRST = true;

// The next psi as the table holds it, float32 RGBA (copied over the table
// after the pass), then L2 as float32 RGBA per texel.
layout(std430, binding = BINDING_ITERATE) buffer IterBuf { uint d[]; } IB;

// The three rows nearest an altitude for ms_read_quadratic(): the middle
// one (1 .. M_H - 2), the altitude's offset from it in rows (-1 .. 1) and,
// for the rows below, at and above it, the horizon cosines and ms_u()'s
// scales.
struct QuadRows {
	int i;
	float f;
	vec3 horizon, below, above;
};

QuadRows quad_rows(float h)
{
	QuadRows c;
	float p = clamp(h / P.SHELL_KM, 0.0, 1.0) * float(M_H - 1);
	c.i = clamp(int(floor(p + 0.5)), 1, M_H - 2);
	c.f = p - float(c.i);
	float dh = P.SHELL_KM / float(M_H - 1);
	c.horizon = vec3(horizon_cos(float(c.i - 1) * dh), horizon_cos(float(c.i) * dh),
			 horizon_cos(float(c.i + 1) * dh));
	c.below = 1.0 / (1.0 + c.horizon);
	c.above = 1.0 / (1.0 - c.horizon);
	return c;
}

// Row row of the table at mu_s, at the row's own u (ms_u(), as ms_taps()).
vec3 ms_row_at(int row, float mh, float below, float above, float mu_s)
{
	Axis x = axis(ms_u(mu_s, mh, below, above), M_W);
	return mix(texelFetch(MultiscatterTex, row * M_W + x.i0).rgb,
		   texelFetch(MultiscatterTex, row * M_W + x.i1).rgb, x.f);
}

// psi where a neighbour of x lies: the parabola through the three nearest
// rows. Where the sunlight dies within a few rows psi is concave in
// altitude, and the linear blend of multiscatter_at() reads every neighbour
// low, an error the iteration carries into every texel (truth/model.c
// mirrors it).
vec3 ms_read_quadratic(QuadRows c, float mu_s)
{
	vec3 a = ms_row_at(c.i - 1, c.horizon.x, c.below.x, c.above.x, mu_s);
	vec3 b = ms_row_at(c.i, c.horizon.y, c.below.y, c.above.y, mu_s);
	vec3 e = ms_row_at(c.i + 1, c.horizon.z, c.below.z, c.above.z, mu_s);
	float f = c.f;
	return max(b + 0.5 * f * (e - a) + 0.5 * f * f * (e - 2.0 * b + a), vec3(0.0));
}

// The sky's light that reaches the ground per unit albedo (its irradiance
// over pi), from psi at the ground psi_g and the sunlight's sunlit (its
// irradiance over pi). At the ground the lower half of the sphere is the
// ground itself, whose radiance is albedo (sunlit + sky), so psi_g = (sky +
// albedo (sunlit + sky)) / 2 with the sky's radiance taken uniform over the
// upper half. Returning albedo psi_g instead, as Hillaire's series does,
// counts half the sky and the ground twice, which matters in a thick
// atmosphere, where the sky, not the sun, lights the ground.
vec3 ground_sky(vec3 psi_g, vec3 sunlit)
{
	return max(2.0 * psi_g - P.albedo.rgb * sunlit, vec3(0.0)) / (1.0 + P.albedo.rgb);
}

void main()
{
	load_params();
	ivec3 at = ms_texels();
	int x0 = at.x, py = at.y, lane = at.z;
	if (x0 >= OUT_W || py >= OUT_H)
		return;

	float h = ms_row_altitude(py);
	vec3 sun[MS_SUN_GROUP];
	ms_row_suns(x0, h, sun);
	const int n_dirs = MS_MARCHED;
	const float norm = MS_NORM;
	float r0 = P.BOTTOM_RADIUS_KM + h;
	mat4x3 scattering_of = mat4x3(0.0), absorption_of = mat4x3(0.0);
	for (int i = 0; i < N_CONST; i++) {
		scattering_of[i] = P.c[i].scattering.rgb;
		absorption_of[i] = P.c[i].absorption.rgb;
	}

	// The light scattered toward x per sun (gathered), and 1 - f as in
	// multiscatter.comp: what leaves or is absorbed.
	vec3 gathered[MS_SUN_GROUP];
	for (int j = 0; j < MS_SUN_GROUP; j++)
		gathered[j] = vec3(0.0);
	vec3 sum_escape = vec3(0.0), sum_returned = vec3(0.0);
	// first: the sunlit ground's first bounce G, as multiscatter.comp has it.
	vec3 first[MS_SUN_GROUP];
	for (int j = 0; j < MS_SUN_GROUP; j++)
		first[j] = vec3(0.0);
	TAlt ground_alt = t_alt(0.0);
	// do-while: lavapipe ends a for loop with one more pass, every lane
	// off (lane < MS_LANES <= n_dirs).
	int k = lane;
	do {
		vec2 ring = cell_ring(k);
		float wk = cell_weight(ring);
		vec3 dir = cell_direction(k, ring);
		float tg, t_end = distance_to_top(h, dir.z);
		bool ground = hits_ground(h, dir.z, tg);
		if (ground)
			t_end = tg;
		float dt = t_end / float(STEPS);
		vec3 tr = vec3(1.0), absorbed = vec3(0.0);
		// do-while: lavapipe ends a for loop with one more step, every
		// lane off (STEPS >= 1).
		int s = 0;
		do {
			float t = (float(s) + 0.5) * dt, rr;
			float hs = altitude_along(h, dir.z, t, rr);
			vec4 dens = densities(hs);
			vec3 scattering = scattering_of * dens, absorption = absorption_of * dens;
			vec3 step_t, w = tr * step_weight(scattering + absorption, dt, step_t);
			QuadRows cr = quad_rows(hs);
			vec3 up = vec3(dir.xy * t, r0 + dir.z * t) / rr, ws = (w * wk) * scattering;
			for (int j = 0; j < MS_SUN_GROUP; j++)
				gathered[j] += ws * ms_read_quadratic(cr, dot(up, sun[j]));
			absorbed += w * absorption;
			tr *= step_t;
		} while (++s < STEPS);
		// The cell's solid angle over the mean cell's (as multiscatter.comp).
		tr *= wk;
		absorbed *= wk;
		vec3 returned = vec3(0.0);
		if (ground && !GROUND_BLACK) {
			vec3 n = vec3(dir.xy * t_end, r0 + dir.z * t_end) / P.BOTTOM_RADIUS_KM;
			returned = tr * P.albedo.rgb;
			for (int j = 0; j < MS_SUN_GROUP; j++) {
				float mu_g = dot(n, sun[j]);
				vec3 sunlit = transmittance_at(ground_alt, mu_g) * (max(mu_g, 0.0) / PI);
				first[j] += returned * sunlit;
				gathered[j] += returned * ground_sky(multiscatter_at(ground_alt, mu_g).rgb, sunlit);
			}
		}
		sum_escape += tr - returned + absorbed;
		sum_returned += returned;
	} while ((k += MS_LANES) < n_dirs);
	// The wide grain: the sums over every lane's cells.
	if (MS_LANES > 1) {
		float v[MS_PARTS];
		for (int c = 0; c < 3; c++) {
			v[c] = gathered[0][c];
			v[3 + c] = first[0][c];
			v[6 + c] = sum_escape[c];
			v[9 + c] = sum_returned[c];
		}
		ms_reduce(v, 12, lane);
		gathered[0] = vec3(v[0], v[1], v[2]);
		first[0] = vec3(v[3], v[4], v[5]);
		sum_escape = vec3(v[6], v[7], v[8]);
		sum_returned = vec3(v[9], v[10], v[11]);
		if (lane != 0)
			return;
	}
	vec3 escape = sum_escape * norm;
	int l2_base = 4 * OUT_W * OUT_H;
	for (int j = 0; j < MS_SUN_GROUP; j++) {
		int i = py * OUT_W + x0 + j;
		if (x0 + j >= OUT_W)
			break;
		vec4 own = texelFetch(MultiscatterTex, i);
		vec3 l2;
		if (ITER_FIRST) {
			// multiscatter.comp stored psi = (L2 + G (1 - f_ground)) /
			// max(escape, 1e-6); here G counts whole, since the ground's
			// own return is ground_sky()'s, which holds no G.
			l2 = own.rgb * max(escape, vec3(1e-6)) + first[j] * (norm * norm) * sum_returned;
			for (int c = 0; c < 3; c++)
				IB.d[l2_base + 4 * i + c] = floatBitsToUint(l2[c]);
		} else {
			l2 = vec3(uintBitsToFloat(IB.d[l2_base + 4 * i]), uintBitsToFloat(IB.d[l2_base + 4 * i + 1]),
				  uintBitsToFloat(IB.d[l2_base + 4 * i + 2]));
		}
		// A, the ground's first bounce's share of psi: the bounce stays,
		// psi grows.
		vec3 psi = l2 + gathered[j] * norm;
		float kept = dot(own.rgb, MS_SHARE_LUM) / max(dot(psi, MS_SHARE_LUM), 1e-30);
		STORE_TEXEL(IB, i, vec4(psi, clamp(own.a * kept, 0.0, 1.0)));
		note_range(psi);
		// The shape (multiscatter.comp's MomentBuf) is L2's, stored
		// relative to psi: it stays what it was in absolute terms, as A
		// does. Each texel is only ever touched by its own invocation, so
		// it is rescaled in place.
		if (MOMENT_CONST >= 0)
			MOB.d[i] *= kept;
	}
	// The table's largest value is the last step's: the engine clears
	// the range before that step.
	flush_range(BINDING_MULTISCATTER - BINDING_TRANSMITTANCE);
}
