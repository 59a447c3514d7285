// aerial_resample.comp - a camera's aerial-perspective volume from the
// panorama of its eye point (aerial.comp marched it): per froxel column,
// the column's direction placed in the panorama once, then per slice a
// bilinear blend of the four columns around it, of the logarithm of the
// radiance (aerial.comp stores it so) and of the transmittance. The panorama has the
// volume's slices, so depth needs no interpolation. Cameras on one eye
// point differ only by orientation; the march they share costs one
// volume, this pass a fraction of one per camera (docs/performance.md).
// gl_GlobalInvocationID.z is the resample job (sky_params.h).
#version 450
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

layout(std430, binding = BINDING_VIEWS) readonly buffer ViewBuf { uvec4 head; AerialJob job[]; } VB;
layout(std430, binding = BINDING_AERIAL) writeonly buffer AerialTexels { uvec4 d[]; } AT;
// The same memory, read through a texel buffer: gathers are vectorized on
// lavapipe where a storage-buffer load with a varying index is a loop.
layout(binding = BINDING_AERIAL_TEX) uniform samplerBuffer AerialTex;

void main()
{
	ivec2 px = ivec2(gl_GlobalInvocationID.xy);
	if (px.x >= OUT_W || px.y >= OUT_H)
		return;
	// VB.head.x: the march jobs, which come first.
	uint z = VB.head.x + gl_GlobalInvocationID.z;
	int out_base = int(VB.job[z].out_texel);
	int pano = int(VB.job[z].panorama_texel);

	// The column's direction exactly as aerial.comp marches a camera's.
	vec2 ndc = (vec2(px) + 0.5) / vec2(OUT_W, OUT_H) * 2.0 - 1.0;
	float tan_half = VB.job[z].tan_half_vfov;
	vec3 dir = normalize(VB.job[z].fwd + ndc.x * tan_half * VB.job[z].aspect * VB.job[z].right +
			     ndc.y * tan_half * VB.job[z].up);

	// The column and row around it: skymap_panorama_uv, the mapping that
	// clients reading a published panorama use.
	int pw = int(VB.job[z].width), ph = int(VB.job[z].height);
	vec2 uv = skymap_panorama_uv(VB.job[z].azimuth0_rad, VB.job[z].azimuth_step_rad,
				     VB.job[z].row0, VB.job[z].row_step, VB.job[z].horizon_rad, pw, ph,
				     VB.job[z].full_circle > 0.5, atan(dir.x, dir.y),
				     asin(clamp(dir.z, -1.0, 1.0)));
	float fu = uv.x * float(pw) - 0.5, fv = uv.y * float(ph) - 0.5;
	int i0 = clamp(int(fu), 0, pw - 2), j0 = clamp(int(fv), 0, ph - 2), i1 = i0 + 1;
	float wu = fu - float(i0), wv = fv - float(j0);
	int a = pano + j0 * pw, b = a + pw;
	for (int k = 0; k < OUT_D; k++) {
		int s = k * pw * ph;
		vec4 lo = mix(texelFetch(AerialTex, a + s + i0), texelFetch(AerialTex, a + s + i1), wu);
		vec4 hi = mix(texelFetch(AerialTex, b + s + i0), texelFetch(AerialTex, b + s + i1), wu);
		vec4 texel = mix(lo, hi, wv);
		texel.rgb = exp(texel.rgb);
		AT.d[out_base + (k * OUT_H + px.y) * OUT_W + px.x] = floatBitsToUint(texel);
		note_range(texel.rgb);
	}
	flush_range(BINDING_AERIAL - BINDING_TRANSMITTANCE);
}
