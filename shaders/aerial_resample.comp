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

layout(std430, binding = BINDING_VIEWS) readonly buffer ViewBuf { vec4 v[]; } VB;
layout(std430, binding = BINDING_AERIAL) writeonly buffer AerialTexels { uvec4 d[]; } AT;
// The same memory, read through a texel buffer: gathers are vectorized on
// lavapipe where a storage-buffer load with a varying index is a loop.
layout(binding = BINDING_AERIAL_TEX) uniform samplerBuffer AerialTex;

const float TWO_PI = 6.28318530717958648;

// A coordinate along the panorama's azimuths: column i0 and weight w of
// column i1 for azimuth az. m0 = (first azimuth, step, ...), m1.y columns,
// m1.w 1 for a full circle (columns wrap), else an arc ending on its
// first and last columns.
void azimuth_taps(float az, vec4 m0, vec4 m1, out int i0, out int i1, out float w)
{
	int n = int(m1.y);
	float du = az - m0.x;
	du -= TWO_PI * floor(du / TWO_PI);
	if (m1.w > 0.5) {
		float f = du / m0.y;
		i0 = int(floor(f));
		w = f - float(i0);
		i0 = i0 % n;
		i1 = (i0 + 1) % n;
		return;
	}
	float span = m0.y * float(n - 1);
	if (du > span)		// outside by rounding: the nearer end
		du = du - span < TWO_PI - du ? span : 0.0;
	float f = clamp(du / m0.y, 0.0, float(n - 1));
	i0 = min(int(f), n - 2);
	w = f - float(i0);
	i1 = i0 + 1;
}

void main()
{
	ivec2 px = ivec2(gl_GlobalInvocationID.xy);
	if (px.x >= OUT_W || px.y >= OUT_H)
		return;
	int job = 1 + AERIAL_JOB_VEC4 * (int(VB.v[0].x) + int(gl_GlobalInvocationID.z));
	vec4 fwd = VB.v[job], right = VB.v[job + 1], cup = VB.v[job + 2];
	vec4 m0 = VB.v[job + 3], m1 = VB.v[job + 4];
	int out_base = int(floatBitsToUint(VB.v[job + 5].x));
	int pano = int(floatBitsToUint(VB.v[job + 5].y));

	// The column's direction exactly as aerial.comp marches a camera's.
	vec2 ndc = (vec2(px) + 0.5) / vec2(OUT_W, OUT_H) * 2.0 - 1.0;
	vec3 dir = normalize(fwd.xyz + ndc.x * fwd.w * right.w * right.xyz + ndc.y * fwd.w * cup.xyz);

	int i0, i1;
	float wu;
	azimuth_taps(atan(dir.x, dir.y), m0, m1, i0, i1, wu);
	int pw = int(m1.y), ph = int(m1.z);
	float e = asin(clamp(dir.z, -1.0, 1.0)) - m1.x;
	float fv = clamp((sign(e) * sqrt(abs(e)) - m0.z) / m0.w, 0.0, float(ph - 1));
	int j0 = min(int(fv), ph - 2);
	float wv = fv - float(j0);
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
