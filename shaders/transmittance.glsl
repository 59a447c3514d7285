// transmittance.glsl - a transmittance texel from its column densities,
// stored: exp(-sum_k ext_k L_k). Written by transmittance.comp (the columns
// kept) and by columns.comp in the same dispatch as the columns.

// The table again a texel per element (one store, one loop over the lanes
// on lavapipe, where STORE_TEXEL's four words take four), and in 8-byte
// units for the binary16 copy: texel i's halves are unit 2 n + i after the
// n float32 texels.
layout(std430, binding = BINDING_TRANSMITTANCE) writeonly buffer TransmittanceTexels { uvec4 d[]; } TT;
layout(std430, binding = BINDING_TRANSMITTANCE) writeonly buffer TransmittanceHalves { uvec2 d[]; } TH;

// Texel i of the OUT_W x OUT_H table from its columns. Its values never
// exceed 1, so with storage=f16 it writes its binary16 copy itself.
void store_transmittance(int i, vec4 column)
{
	vec3 tau = vec3(0.0);
	for (int k = 0; k < N_CONST; k++)
		tau += (P.c[k].scattering.rgb + P.c[k].absorption.rgb) * column[k];
	vec3 t = exp(-tau);
	TT.d[i] = floatBitsToUint(vec4(t, 1.0));
	// storage=f16: the binary16 copy after the float32 texels, scaled by
	// 2^15 (exactly: at most 32768, the largest power of two below 65504).
	if (STORAGE_F16) {
		float s = uintBitsToFloat(uint(127 - SKY_F16_TRANSMITTANCE_LOG2) << 23);
		TH.d[2 * OUT_W * OUT_H + i] = uvec2(packHalf2x16(t.rg * s), packHalf2x16(vec2(t.b * s, 1.0)));
	}
}
