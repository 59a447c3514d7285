// transmittance.comp - transmittance to the top of the atmosphere per
// (altitude, zenith cosine), Bruneton's mapping: exp(-sum_k ext_k L_k) from
// the column densities L_k that columns.comp computed for the same texels.
// A change of coefficients alone runs only this pass. Its values never
// exceed 1, so with storage=f16 it writes its binary16 copy itself.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// The table again in 8-byte units, for the binary16 copy: texel i's halves
// are unit 2 n + i after the n float32 texels (one store, one loop over the
// lanes on lavapipe).
layout(std430, binding = BINDING_TRANSMITTANCE) writeonly buffer TransmittanceHalves { uvec2 d[]; } TH;

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
	vec3 t = exp(-tau);
	STORE_TEXEL(TB, i, vec4(t, 1.0));
	// storage=f16: the binary16 copy after the float32 texels, scaled by
	// 2^15 (exactly: at most 32768, the largest power of two below 65504).
	if (STORAGE_F16) {
		float s = uintBitsToFloat(uint(127 - SKY_F16_TRANSMITTANCE_LOG2) << 23);
		TH.d[2 * OUT_W * OUT_H + i] = uvec2(packHalf2x16(t.rg * s), packHalf2x16(vec2(t.b * s, 1.0)));
	}
}
