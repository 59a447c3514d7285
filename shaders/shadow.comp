// shadow.comp - the Beer shadow maps (Hillaire, SIGGRAPH 2020 course): per
// texel of a light's map (z: 0 sun, 1 moon), the light's ray through the
// layers, marched in STEPS steps over its piece between the lowest base
// and the highest top inside the region, the density the layers' envelope
// (coverage table x profile x extinction: the detail noise's cells are
// below a texel) gives. RGBA32F = (front depth km from the map's plane,
// mean extinction per km over the cloud span, the column's optical depth,
// the terrain's opaque depth or SKY_SHADOW_NO_TERRAIN_KM).
#version 450
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"
#include "clouds.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
layout(std430, binding = BINDING_SHADOW) writeonly buffer ShadowTexels { vec4 d[]; } ST;

// The layers' extinction per km at q from the coverage table, bilinear.
float envelope_at(vec3 q)
{
	float e = CL.FIELD_EXTENT_KM, k = CL.FIELD_TEXELS_PER_KM;
	float x = clamp((q.x + e) * k - 0.5, 0.0, float(CLOUD_W - 1));
	float y = clamp((q.y + e) * k - 0.5, 0.0, float(CLOUD_W - 1));
	int i = min(int(x), CLOUD_W - 2), j = min(int(y), CLOUD_W - 2);
	float fx = x - float(i), fy = y - float(j);
	int b = j * CLOUD_W + i;
	vec4 v = mix(mix(texelFetch(CloudTex, b), texelFetch(CloudTex, b + 1), fx),
		     mix(texelFetch(CloudTex, b + CLOUD_W), texelFetch(CloudTex, b + CLOUD_W + 1), fx), fy);
	float h = skycloud_altitude(P.BOTTOM_RADIUS_KM, q), sum = 0.0;
	for (int l = 0; l < CLOUD_LAYERS; l++) {
		float hf = (h - CL.layer[l].base_km) * CL.layer[l].inv_thickness_per_km;
		if (!(hf > 0.0 && hf < 1.0))
			continue;
		float c = skycloud_saturate(v[l] + CL.layer[l].anvil * hf * hf);
		sum += CL.layer[l].extinction_per_km * c * skycloud_profile(CL.layer[l], hf);
	}
	return sum;
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
	float lo = 1e30, hi = -1e30;
	for (int l = 0; l < CLOUD_LAYERS; l++) {
		lo = min(lo, CL.layer[l].base_km);
		hi = max(hi, CL.layer[l].top_km);
	}
	float rb = P.BOTTOM_RADIUS_KM, a0, a1, b0, b1, t0 = 0.0, t1 = 0.0;
	if (skycloud_sphere(rb, hi, o, d, a0, a1)) {
		t0 = max(a0, 0.0);
		t1 = a1;
		// Down to the base shell where the ray meets it; a ray that
		// grazes it crosses the band once, along its whole chord.
		if (skycloud_sphere(rb, lo, o, d, b0, b1) && b0 > t0)
			t1 = min(t1, b0);
		clip_region(o, d, CL.FIELD_EXTENT_KM, t0, t1);
	}
	vec4 texel = vec4(1e30, 0.0, 0.0, SKY_SHADOW_NO_TERRAIN_KM);
	if (t1 > t0) {
		float dt = (t1 - t0) / float(STEPS), tau = 0.0, front = 1e30, back = 0.0;
		for (int k = 0; k < STEPS; k++) {
			float t = t0 + (float(k) + 0.5) * dt;
			float ext = envelope_at(o + t * d);
			if (ext > 0.0) {
				front = min(front, t - 0.5 * dt);
				back = t + 0.5 * dt;
				tau += ext * dt;
			}
		}
		if (tau > 0.0)
			texel.xyz = vec3(front, tau / max(back - front, dt), tau);
	}
	ST.d[(px.z * SHADOW_W + px.y) * SHADOW_W + px.x] = texel;
}
