// pack.comp - the binary16 copy of the tables that storage=f16 publishes.
//
// Every pass computes its table in float32, whatever the storage; with
// storage=f16 this pass writes each computed table's binary16 copy into the
// same buffer, after its float32 texels (the engine copies it out from
// there). RGB is scaled by 2^-k, the power of two that brings the table's
// largest |RGB| M to at most 65504, the largest finite half, and above
// half of it: nothing overflows, and every value down to about M 2^-29
// stays a normal half with 11 significant bits, wherever the sky's
// brightness lies (a sunlit Mars above 65504 cd/m2, moonlight near 1e-3).
// A power of two scales exactly, so the only rounding is the half's own.
// A (a transmittance or a share, within [0, 1]) is not scaled. The passes
// found M as they stored the float32 texels (note_range in common.glsl).
// Transmittance, never above 1, packs itself (transmittance.glsl).
//
// One dispatch after the last pass packs every table of PACK_MASK, one
// after the other: the tables are constants, since lavapipe runs both sides
// of a branch with lanes masked and a table chosen at run time would cost
// every table's loads. Each invocation packs pairs of texels, two float32
// texels read and their halves stored with one vector access each (a loop
// over the lanes on lavapipe either way).
#version 450
#extension GL_GOOGLE_include_directive : require
#include "sky_params.h"

layout(constant_id = SPEC_PACK_MASK) const int PACK_MASK = 0;
layout(local_size_x = 64) in;

// The tables' memory in 16-byte units: float32 texel i is unit i, the
// halves of texels 2p and 2p + 1 unit n + p for a table of n texels (an odd
// table's last unit holds its last texel twice: the engine allocates it).
layout(std430, binding = BINDING_MULTISCATTER) buffer MultiscatterQuads { uvec4 d[]; } MQ;
layout(std430, binding = BINDING_SKYVIEW) buffer SkyviewQuads { uvec4 d[]; } SQ;
layout(std430, binding = BINDING_AERIAL) buffer AerialQuads { uvec4 d[]; } AQ;

// struct gpu_pack in sky_params.h.
layout(std430, binding = BINDING_PACK) buffer PackBuf {
	uint texels[SKY_PACK_TABLES];
	uint max_bits[SKY_PACK_TABLES];
	int scale_log2[SKY_PACK_TABLES];
} PB;

vec4 load_texel(int t, uint i)
{
	uvec4 a;
	if (t == 1)
		a = MQ.d[i];
	else if (t == 2)
		a = SQ.d[i];
	else
		a = AQ.d[i];
	return uintBitsToFloat(a);
}

void store_quad(int t, uint i, uvec4 h)
{
	if (t == 1)
		MQ.d[i] = h;
	else if (t == 2)
		SQ.d[i] = h;
	else
		AQ.d[i] = h;
}

uvec2 halves(vec4 v, float s)
{
	return uvec2(packHalf2x16(v.xy * vec2(s, s)), packHalf2x16(vec2(v.z * s, v.w)));
}

// k for the largest magnitude's bits m: the smallest integer with
// M 2^-k <= 65504 = 1.9990234375 2^15 (mantissa bits 0x7fe000), at least
// -126 so that 2^-k stays a float; 0 for a table of zeros or one that is
// not finite (whose infinities and NaN then show as such).
int scale_log2(uint m)
{
	if (m == 0u || m >= 0x7f800000u)
		return 0;
	int e = int(m >> 23) - 127;
	return max(e - 15 + ((m & 0x7fffffu) > 0x7fe000u ? 1 : 0), -126);
}

// Packs table t (a constant where it is called) over the whole dispatch.
void pack_table(int t)
{
	uint n = PB.texels[t], stride = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
	int k = scale_log2(PB.max_bits[t]);
	float s = uintBitsToFloat(uint(127 - k) << 23);	// 2^-k, exactly
	if (gl_GlobalInvocationID.x == 0u)
		PB.scale_log2[t] = k;
	for (uint p = gl_GlobalInvocationID.x; 2 * p < n; p += stride)
		store_quad(t, n + p, uvec4(halves(load_texel(t, 2 * p), s),
					   halves(load_texel(t, min(2 * p + 1, n - 1)), s)));
}

void main()
{
	if ((PACK_MASK & 2) != 0)
		pack_table(1);		// multi-scattering
	if ((PACK_MASK & 4) != 0)
		pack_table(2);		// sky-view
	if ((PACK_MASK & 8) != 0)
		pack_table(3);		// aerial perspective, every view's volume
}
