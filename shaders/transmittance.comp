// transmittance.comp - transmittance to the top of the atmosphere per
// (altitude, zenith cosine), Bruneton's mapping, steps that cover the whole
// ray (no sample offset that drops its end).
#version 450
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

void main()
{
	ivec2 px = ivec2(gl_GlobalInvocationID.xy);
	if (px.x >= OUT_W || px.y >= OUT_H)
		return;

	float rb = P.planet.x, shell = P.planet.z;
	float H = sqrt(shell * (2.0 * rb + shell));
	float x_mu = tex_to_unit((float(px.x) + 0.5) / float(OUT_W), OUT_W);
	float x_r = tex_to_unit((float(px.y) + 0.5) / float(OUT_H), OUT_H);
	float rho = H * x_r;
	float r = sqrt(rho * rho + rb * rb);
	float h = rho * rho / (r + rb);
	float d_min = shell - h, d_max = rho + H;
	float d = d_min + x_mu * (d_max - d_min);
	float mu = d <= 0.0 ? 1.0 : clamp((H * H - rho * rho - d * d) / (2.0 * r * d), -1.0, 1.0);

	// Each step integrates every layer exactly for a linear change of
	// altitude (sinh(x) / x); a midpoint rule at 2.5 km steps would read a
	// 1.2 km scale height 16 % thin.
	// At the top row h rounds above the shell and d_min below 0: a negative
	// step would make exp(-tau dt) > 1.
	float dt = max(d, 0.0) / float(STEPS), rr;
	vec3 tau = vec3(0.0);
	float ha = h;
	for (int i = 0; i < STEPS; i++) {
		float hb = altitude_along(h, mu, float(i + 1) * dt, rr);
		for (int k = 0; k < N_CONST; k++)
			tau += mean_density(k, ha, hb) * (P.C[k].scattering.rgb + P.C[k].absorption.rgb);
		ha = hb;
	}
	STORE_TEXEL(TB, px.y * OUT_W + px.x, vec4(exp(-tau * dt), 1.0));
}
