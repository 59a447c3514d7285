// shadow.comp - the Beer shadow maps (Hillaire, SIGGRAPH 2020 course): per
// texel of a light's map (z: 0 sun, 1 moon), the light's ray through each
// layer's shell inside the region, marched in the steps its piece needs,
// the density the layer's envelope gives (coverage table x profile x
// extinction: the detail noise's cells are below a texel), a partial
// cover taken as that share of the texel clouded. RGBA32F = (front depth
// km from the map's plane, mean extinction per km over the cloud span, the
// column's optical depth, the terrain's opaque depth or
// SKY_SHADOW_NO_TERRAIN_KM).
#version 450
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"
#include "clouds.glsl"
#include "terrain.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
layout(std430, binding = BINDING_SHADOW) writeonly buffer ShadowTexels { vec4 d[]; } ST;

// Layer L's extinction per km at q: its envelope from the coverage
// table, bilinear; ret_cover the cover there. L, e and k: private copies
// (as load_params: lavapipe reloads a buffer read inside a loop at every
// use).
float envelope_at(SkycloudLayer L, float e, float k, vec3 q, out float ret_cover)
{
	float h = skycloud_altitude(P.BOTTOM_RADIUS_KM, q);
	float hf = (h - L.base_km) * L.inv_thickness_per_km;
	ret_cover = 0.0;
	if (!(hf > 0.0 && hf < 1.0))
		return 0.0;
	float x = clamp((q.x + e) * k - 0.5, 0.0, float(CLOUD_W - 1));
	float y = clamp((q.y + e) * k - 0.5, 0.0, float(CLOUD_W - 1));
	int i = min(int(x), CLOUD_W - 2), j = min(int(y), CLOUD_W - 2);
	float fx = x - float(i), fy = y - float(j);
	int b = j * CLOUD_W + i;
	uint ch = L.index & 3u;
	float c0 = mix(mix(texelFetch(CloudTex, b)[ch], texelFetch(CloudTex, b + 1)[ch], fx),
		       mix(texelFetch(CloudTex, b + CLOUD_W)[ch], texelFetch(CloudTex, b + CLOUD_W + 1)[ch], fx), fy);
	// skycloudmarch.h's skycloud_density_cov: the anvil widens only
	// where the table has cover.
	if (!(c0 > 0.0))
		return 0.0;
	float c = skycloud_saturate(c0 + L.anvil * hf * hf);
	ret_cover = c;
	return L.extinction_per_km * c * skycloud_profile(L, hf);
}

// The optical depth of the ray's piece over one coverage texel, tau at
// the table's cover and tau_full at full cover: the bilinear cover c at a
// cloud's edge is the share of cloud in the texel, whose edge is sharp
// (coverage_edge 0.04 of the fBm's spread 0.28), so the piece crosses
// cloud over that share of the map texel and gap over the rest, 1 - c +
// c exp(-tau_full) of light through, not exp(-c tau_full). c: the cover
// along the piece, weighed by the density. The pieces over successive
// texels meet different parts of the field: their optical depths add.
float partial_cover_tau(float tau, float tau_full)
{
	if (!(tau > 0.0))
		return 0.0;
	float c = tau / tau_full;
	return c < 1.0 ? -log(1.0 - c + c * exp(-tau_full)) : tau_full;
}

// The ray o - t l's piece [t0, t1] inside the region's square (its east
// and north components within the half-width e).
void clip_region(vec3 o, vec3 d, float e, inout float t0, inout float t1)
{
	for (int k = 0; k < 2; k++) {
		if (abs(d[k]) < 1e-9) {
			if (abs(o[k]) > e)
				t1 = t0;
			continue;
		}
		float a = (-e - o[k]) / d[k], b = (e - o[k]) / d[k];
		t0 = max(t0, min(a, b));
		t1 = min(t1, max(a, b));
	}
}

// The depth along o + t d (km from the map's plane) where the ray first
// goes below the terrain, or SKY_SHADOW_NO_TERRAIN_KM. Its piece inside
// the square's columns and below the sphere of the terrain's top is
// marched in steps of about half a texel across the ground, at most
// SKY_SHADOW_TERRAIN_STEPS (a piece longer than that many half texels
// takes longer steps and can miss a ridge narrower than one), then the
// crossing is refined by three secant steps inside the bracket.
float terrain_depth_km(vec3 o, vec3 d, float rb)
{
	float half_km = CL.TERRAIN_HALF_KM, t0 = 0.0, t1 = 1e30, a0, a1;
	if (!(half_km > 0.0) || !skycloud_sphere(rb, CL.TERRAIN_TOP_KM, o, d, a0, a1))
		return SKY_SHADOW_NO_TERRAIN_KM;
	t0 = max(a0, 0.0);
	t1 = a1;
	clip_region(o, d, half_km, t0, t1);
	if (!(t1 > t0))
		return SKY_SHADOW_NO_TERRAIN_KM;
	float texels_per_km = float(max(CL.TERRAIN_WIDTH_TEXELS, CL.TERRAIN_HEIGHT_TEXELS)) / (2.0 * half_km);
	float across = max(length(d.xy) * texels_per_km, 1e-6);
	int n = clamp(int(ceil(2.0 * (t1 - t0) * across)), 2, SKY_SHADOW_TERRAIN_STEPS);
	float dt = (t1 - t0) / float(n), ta = t0, ca = terrain_clearance_km(rb, o + t0 * d);
	if (ca <= 0.0)
		return t0;
	for (int k = 1; k <= n; k++) {
		float tb = t0 + float(k) * dt, cb = terrain_clearance_km(rb, o + tb * d);
		if (cb <= 0.0) {
			for (int r = 0; r < 3; r++) {
				float tm = ta + (tb - ta) * ca / (ca - cb);
				float cm = terrain_clearance_km(rb, o + tm * d);
				if (cm > 0.0) {
					ta = tm;
					ca = cm;
				} else {
					tb = tm;
					cb = cm;
				}
			}
			return tb;
		}
		ta = tb;
		ca = cb;
	}
	return SKY_SHADOW_NO_TERRAIN_KM;
}

void main()
{
	load_params();
	ivec3 px = ivec3(gl_GlobalInvocationID);
	if (px.x >= SHADOW_W || px.y >= SHADOW_W)
		return;
	ShadowFrame f = CL.frame[px.z];
	vec3 d = -f.l.xyz;
	vec3 o = (f.U_MIN_KM + (float(px.x) + 0.5) / f.U_TEXELS_PER_KM) * f.u.xyz +
		 (f.V_MIN_KM + (float(px.y) + 0.5) / f.V_TEXELS_PER_KM) * f.v.xyz + f.PLANE_KM * f.l.xyz;
	// Each layer's shell on its own, in as many steps as its piece
	// crosses coverage texels (two a texel, at least four for the
	// profile, at most STEPS): a high light crosses a thin layer in a
	// few, and the gaps between layers cost nothing.
	float rb = P.BOTTOM_RADIUS_KM, tau = 0.0, front = 1e30, back = 0.0;
	float e = CL.FIELD_EXTENT_KM, k_texels = CL.FIELD_TEXELS_PER_KM;
	float across = length(d.xy) * k_texels;
	for (int l = 0; l < CLOUD_LAYERS; l++) {
		SkycloudLayer L = CL.layer[l];
		float a0, a1, b0, b1, t0 = 0.0, t1 = 0.0;
		if (skycloud_sphere(rb, L.top_km, o, d, a0, a1)) {
			t0 = max(a0, 0.0);
			t1 = a1;
			// Down to the base shell where the ray meets it; a ray that
			// grazes it crosses the layer once, along its whole chord.
			if (skycloud_sphere(rb, L.base_km, o, d, b0, b1) && b0 > t0)
				t1 = min(t1, b0);
			clip_region(o, d, e, t0, t1);
		}
		if (!(t1 > t0))
			continue;
		int n = clamp(int(ceil(2.0 * (t1 - t0) * across)), 4, STEPS);
		float dt = (t1 - t0) / float(n), seg_tau = 0.0, seg_full = 0.0;
		int seg = -1;
		for (int k = 0; k < n; k++) {
			float t = t0 + (float(k) + 0.5) * dt;
			float cover, ext = envelope_at(L, e, k_texels, o + t * d, cover);
			int texel_k = int(t * across);
			if (texel_k != seg) {
				tau += partial_cover_tau(seg_tau, seg_full);
				seg_tau = seg_full = 0.0;
				seg = texel_k;
			}
			if (ext > 0.0) {
				front = min(front, t - 0.5 * dt);
				back = max(back, t + 0.5 * dt);
				seg_tau += ext * dt;
				seg_full += ext / cover * dt;
			}
		}
		tau += partial_cover_tau(seg_tau, seg_full);
	}
	// No cloud: (0, 0, 0), which a bilinear filter of the texels blends
	// into a cloud's edge as the clear it is.
	vec4 texel = vec4(0.0, 0.0, 0.0, terrain_depth_km(o, d, rb));
	if (tau > 0.0)
		texel.xyz = vec3(front, tau / (back - front), tau);
	ST.d[(px.z * SHADOW_W + px.y) * SHADOW_W + px.x] = texel;
}
