// transmittance.comp - transmittance to the top of the atmosphere per
// (altitude, zenith cosine), Bruneton's mapping: exp(-sum_k ext_k L_k) from
// the column densities L_k that columns.comp computed for the same texels.
// A change of coefficients alone runs only this pass.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

void main()
{
	load_params();
	ivec2 px = ivec2(gl_GlobalInvocationID.xy);
	if (px.x >= OUT_W || px.y >= OUT_H)
		return;
	int i = px.y * OUT_W + px.x;
	vec4 column = CB.d[i];
	vec3 tau = vec3(0.0);
	for (int k = 0; k < N_CONST; k++)
		tau += (P.c[k].scattering.rgb + P.c[k].absorption.rgb) * column[k];
	STORE_TEXEL(TB, i, vec4(exp(-tau), 1.0));
}
