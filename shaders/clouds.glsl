// clouds.glsl - what the cloud passes and the sky marches share: the
// layers' block, the coverage table and the shadow maps as lookups, the
// cloud's optical depth toward a light at a point and the layers'
// occlusion of the sky (docs/clouds.md, "In the tables"). Included after
// common.glsl; the maps are read only where SHADOW_W > 0 (a layer or the
// terrain casts), the layers only where CLOUD_LAYERS > 0.

#include "skycloud.glsl"

// struct ShadowFrame and the named lanes: sky_params.h.
layout(std430, binding = BINDING_CLOUDS) readonly buffer CloudBlock {
	SkycloudLayer layer[SKYCLOUD_MAX_LAYERS];
	vec4 field;
	vec4 terrain;
	uvec4 terrain_size;
	ShadowFrame frame[2];
} CL;
layout(binding = BINDING_CLOUD_TEX) uniform samplerBuffer CloudTex;
layout(binding = BINDING_SHADOW_TEX) uniform samplerBuffer ShadowTex;

layout(constant_id = SPEC_SHADOW_W) const int SHADOW_W = 1;	// a shadow map's width
layout(constant_id = SPEC_CLOUD_W) const int CLOUD_W = 1;	// the coverage table's

// Private copies, made once per invocation by load_clouds() (as
// load_params(): lavapipe reloads a buffer read inside a loop at every
// use): the lights' frames, and per layer (top km, 1 / thickness, the
// vertical optical depth at full cover, cover) for cloud_sky_open.
ShadowFrame cloud_frame[2];
vec4 cloud_column[SKYCLOUD_MAX_LAYERS];

void load_clouds()
{
	if (SHADOW_W == 0)
		return;
	cloud_frame[0] = CL.frame[0];
	cloud_frame[1] = CL.frame[1];
	for (int i = 0; i < CLOUD_LAYERS; i++)
		cloud_column[i] = vec4(CL.layer[i].top_km, CL.layer[i].inv_thickness_per_km,
				       CL.layer[i].extinction_per_km * (CL.layer[i].top_km - CL.layer[i].base_km) *
					       CL.layer[i].profile_integral,
				       CL.layer[i].cover);
}

// The optical depth of one map texel's column at depth d (km from the
// map's plane): Beer's law in the cloud span, front depth, mean
// extinction, capped at the column's whole (docs/clouds.md); beyond the
// terrain's opaque depth the light is gone.
float shadow_texel_tau(vec4 s, float d)
{
	float tau = min(s.z, s.y * max(d - s.x, 0.0));
	return d > s.w ? 80.0 : tau;
}

// The cloud's optical depth toward light (0 sun, 1 moon) at q (km, the
// observer's east-north-up frame from the ground under it), from the
// light's map, bilinear between its texels; 0 outside the
// map (no cloud beyond the region).
float cloud_tau(int light, vec3 q)
{
	ShadowFrame f = cloud_frame[light];
	float x = (dot(q, f.u.xyz) - f.U_MIN_KM) * f.U_TEXELS_PER_KM - 0.5;
	float y = (dot(q, f.v.xyz) - f.V_MIN_KM) * f.V_TEXELS_PER_KM - 0.5;
	float top = float(SHADOW_W) - 0.5;
	if (!(x > -0.5 && y > -0.5 && x < top && y < top))
		return 0.0;
	x = clamp(x, 0.0, float(SHADOW_W - 1));
	y = clamp(y, 0.0, float(SHADOW_W - 1));
	int i = min(int(x), SHADOW_W - 2), j = min(int(y), SHADOW_W - 2);
	float fx = x - float(i), fy = y - float(j);
	float d = f.PLANE_KM - dot(q, f.l.xyz);
	int base = light * SHADOW_W * SHADOW_W + j * SHADOW_W + i;
	float t00 = shadow_texel_tau(texelFetch(ShadowTex, base), d);
	float t10 = shadow_texel_tau(texelFetch(ShadowTex, base + 1), d);
	float t01 = shadow_texel_tau(texelFetch(ShadowTex, base + SHADOW_W), d);
	float t11 = shadow_texel_tau(texelFetch(ShadowTex, base + SHADOW_W + 1), d);
	return mix(mix(t00, t10, fx), mix(t01, t11, fx), fy);
}

// The share of light the cloud lets through toward light at q.
float cloud_light(int light, vec3 q)
{
	return exp(-cloud_tau(light, q));
}

// 1 - skycloud_sky_occlusion(h) for the block's layers: the same formula
// from the private copy (load_clouds).
float cloud_sky_open(float h)
{
	if (CLOUD_LAYERS == 0)
		return 1.0;
	float open = 1.0;
	for (int i = 0; i < CLOUD_LAYERS; i++) {
		float above = skycloud_saturate((cloud_column[i].x - h) * cloud_column[i].y);
		open *= 1.0 - cloud_column[i].w * (1.0 - exp(-cloud_column[i].z * above));
	}
	return 1.0 - skycloud_saturate(1.0 - open);
}

// At a march step at q, altitude h: sets the sky the layers leave open
// for the multiply scattered light (cloud_ms_open) and returns the share
// of the sun's light the cloud lets through.
float cloud_step(vec3 q, float h)
{
	cloud_ms_open = cloud_sky_open(h);
	return exp(-cloud_tau(0, q));
}
