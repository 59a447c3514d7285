// shadow.comp - the Beer shadow maps (Hillaire, SIGGRAPH 2020 course): per
// texel of a light's map (z: 0 sun, 1 moon), the light's ray through each
// layer's shell inside the region, marched in the steps its piece needs,
// the density the layer's envelope gives (coverage table x profile x
// extinction: the detail noise's cells are below a texel), a partial
// cover taken as that share of the texel clouded. RGBA32F = (front depth
// km from the map's plane, mean extinction per km over the cloud span, the
// column's optical depth, the terrain's opaque depth or
// SKY_SHADOW_NO_TERRAIN_KM). With ice and water layers one above the other
// (CLOUD_PHASES), each texel's ice optical depth too, after the two maps.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"
#include "clouds.glsl"
#include "terrain.glsl"

layout(constant_id = SPEC_TERRAIN) const bool TERRAIN = false;
layout(local_size_x = 8, local_size_y = 8) in;
layout(std430, binding = BINDING_SHADOW) writeonly buffer ShadowTexels { vec4 d[]; } ST;

// Layer L's extinction per km at q: its envelope from the coverage
// table, bilinear; ret_full what it would be at full cover, ret_gap
// ret_full times the share of the texel without cloud (0 exactly at full
// cover, which a ratio of sums would round either way). L, e and k: private copies
// (as load_params: lavapipe reloads a buffer read inside a loop at every
// use).
float envelope_at(SkycloudLayer L, float e, float k, vec3 q, out float ret_full, out float ret_gap)
{
	float h = skycloud_altitude(P.BOTTOM_RADIUS_KM, q);
	float hf = (h - L.base_km) * L.inv_thickness_per_km;
	ret_full = ret_gap = 0.0;
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
	ret_full = L.extinction_per_km * skycloud_profile(L, hf);
	ret_gap = ret_full * (1.0 - c);
	return ret_full * c;
}

// The ray's piece over one coverage texel, of optical depth tau_full at
// full cover and gap of it missing where the table's cover c < 1: the
// bilinear cover at a cloud's edge is the share of cloud in the texel,
// whose edge is sharp (coverage_edge 0.04 of the fBm's spread 0.28), so
// the piece crosses cloud over that share of the map texel and gap over
// the rest, 1 - c + c exp(-tau_full) of light through, not exp(-c
// tau_full). c: the cover along the piece, weighed by the density. The
// pieces over successive texels meet different parts of the field: their
// transmittances multiply, into tr (its mantissa, its power of two in
// tr_exp2, so that no product underflows), and a fully covered piece's
// optical depth adds to tau. One logarithm per texel of the map then, not
// one per piece.
void add_piece(float tau_full, float gap, inout float tau, inout float tr, inout int tr_exp2)
{
	if (!(tau_full > gap))
		return;
	float open = gap / tau_full;	// 1 - c
	if (open > 0.0) {
		int e2;
		tr = frexp(tr * (open + (1.0 - open) * exp(-tau_full)), e2);
		tr_exp2 += e2;
	} else {
		tau += tau_full;
	}
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
	float rb = P.BOTTOM_RADIUS_KM, tau = 0.0, tr = 1.0, front = 1e30, back = 0.0;
	int tr_exp2 = 0;
	// The ice layers' own share, accumulated alike (CLOUD_PHASES).
	float tau_ice = 0.0, tr_ice = 1.0;
	int tr_ice_exp2 = 0;
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
		bool ice = CLOUD_PHASES != CLOUD_PHASES_ONE && L.type == CLOUD_TYPE_CIRRUS;
		int n = clamp(int(ceil(2.0 * (t1 - t0) * across)), 4, STEPS);
		float dt = (t1 - t0) / float(n), seg_full = 0.0, seg_gap = 0.0;
		int seg = -1, k = 0;
		// do-while: lavapipe ends a for loop with one more step, every
		// lane off (n >= 4).
		do {
			float t = t0 + (float(k) + 0.5) * dt;
			float full, gap, ext = envelope_at(L, e, k_texels, o + t * d, full, gap);
			int texel_k = int(t * across);
			if (texel_k != seg) {
				add_piece(seg_full, seg_gap, tau, tr, tr_exp2);
				if (ice)
					add_piece(seg_full, seg_gap, tau_ice, tr_ice, tr_ice_exp2);
				seg_full = seg_gap = 0.0;
				seg = texel_k;
			}
			if (ext > 0.0) {
				front = min(front, t - 0.5 * dt);
				back = max(back, t + 0.5 * dt);
				seg_full += full * dt;
				seg_gap += gap * dt;
			}
		} while (++k < n);
		add_piece(seg_full, seg_gap, tau, tr, tr_exp2);
		if (ice)
			add_piece(seg_full, seg_gap, tau_ice, tr_ice, tr_ice_exp2);
	}
	tau -= log(tr) + float(tr_exp2) * 0.69314718;
	// No cloud: (0, 0, 0), which a bilinear filter of the texels blends
	// into a cloud's edge as the clear it is. Without a height field the
	// terrain's march is compiled out: lavapipe would run its code with
	// every lane off.
	vec4 texel = vec4(0.0, 0.0, 0.0, TERRAIN ? terrain_depth_km(o, d, rb) : SKY_SHADOW_NO_TERRAIN_KM);
	if (tau > 0.0)
		texel.xyz = vec3(front, tau / (back - front), tau);
	int at = (px.z * SHADOW_W + px.y) * SHADOW_W + px.x;
	ST.d[at] = texel;
	if (CLOUD_PHASES != CLOUD_PHASES_ONE) {
		tau_ice -= log(tr_ice) + float(tr_ice_exp2) * 0.69314718;
		ST.d[2 * SHADOW_W * SHADOW_W + at / 4][at & 3] = min(tau_ice, texel.z);
	}
}
