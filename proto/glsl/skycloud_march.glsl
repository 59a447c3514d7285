// skycloud_march.glsl - drawing the cloud field in a render client's
// shaders: the shadow of the layers on a point from a light's Beer shadow
// map, a march of the layers along a view ray lit from the sky's tables,
// and the compositing of clouds with the sky and aerial perspective.
// proto/skycloudmarch.h function for function (test_glsl_cloud_march
// checks the pair on the device); the model, its choices and its costs:
// docs/clouds.md, "Drawing clouds in a client".
//
// Use (after sky.glsl's declarations):
//
//     #include "skycloud_march.glsl"         // includes sky.glsl, skycloud.glsl
//     layout(std430, binding = 4) readonly buffer Clouds {
//         SkycloudLayer layers[SKYCLOUD_MAX_LAYERS];
//         SkycloudScene scene;
//         SkycloudLight sun;
//     };
//     layout(binding = 5) uniform sampler2D coverage_tex;   // the cloud table
//     layout(binding = 6) uniform sampler2D sun_shadow_tex;  // the sun's Beer map
//     ...
//     SkycloudSample c = skycloud_march(sky, transmittance_tex, multiscatter_tex,
//         coverage_tex, sun_shadow_tex, layers, scene, sun, eye_km, dir, far_km,
//         SKYCLOUD_MARCH_STEPS_MEDIUM, 0, jitter);
//     vec4 air = sky_aerial_dir(sky, aerial_tex, dir, c.depth_km);
//     vec3 L = skycloud_composite(behind, c, air);
//
// Every texture is read as sky.glsl reads a table (sky_read_2d: linear
// filtering, CLAMP_TO_EDGE; SKY_GLSL_EXACT_FILTER filters in the shader,
// which a shadow map in R32G32B32A32_SFLOAT needs where the device cannot
// filter that format). A sampler that the call does not read (the coverage
// table when the scene's extent is 0, the shadow map when light_steps > 0
// or the light has none) must still be bound to some texture.
// Plain GLSL 4.50, no extensions, no bindings, no globals beyond constants.
#ifndef SKYCLOUD_MARCH_GLSL
#define SKYCLOUD_MARCH_GLSL

#include "sky.glsl"
#include "skycloud.glsl"

#define SKYCLOUD_MARCH_STEPS_LOW 32
#define SKYCLOUD_MARCH_STEPS_MEDIUM 64
#define SKYCLOUD_MARCH_STEPS_HIGH 128
#define SKYCLOUD_MARCH_MAX_OCTAVES 4
const float SKYCLOUD_MARCH_MIN_TRANSMITTANCE = 1e-3;
const float SKYCLOUD_SHADOW_OPAQUE = 1e30;

// struct skycloud_shadow_frame: u = dot(row_u, vec4(p, 1)), v likewise,
// depth along the light = dot(row_depth, vec4(p, 1)); bias.x the terrain's
// bias in km.
struct SkycloudShadowFrame {
	vec4 row_u, row_v, row_depth;
	vec4 bias;
};

// struct skycloud_scene, in vec4s (std140 and std430 alike).
struct SkycloudScene {
	vec4 phase_g;		// per layer
	vec4 albedo;		// per layer
	vec4 octaves;		// x: count (1..4), y: a (extinction), z: b (scattering), w: c (phase g)
	vec4 field;		// xy: the wind's offset km, z: the number of layers,
				// w: the coverage table's half-width km (0: the field's own coverage)
	vec4 ambient;		// rgb: sky irradiance lx, scattered as E / pi; w: 1 the light
				// diffused through the layers in place of the octaves past the first
	vec4 table;		// xy: the coverage table's shift km (table_shift_km), zw: 0
};

// struct skycloud_light: dir.xyz toward the light, dir.w 1 when it has a
// shadow map (0: none); illuminance.rgb at the top of the atmosphere.
struct SkycloudLight {
	vec4 dir;
	vec4 illuminance;
	SkycloudShadowFrame frame;
};

// struct skycloud_sample.
struct SkycloudSample {
	vec3 radiance;
	float transmittance;
	float depth_km;
};

vec2 skycloud_table_uv(float extent_km, vec2 xy)
{
	return 0.5 + 0.5 * xy / extent_km;
}

// The light's optical depth through the clouds at p from its shadow map:
// skycloud_shadow_depth.
float skycloud_shadow_depth(sampler2D map, SkycloudShadowFrame f, vec3 p)
{
	vec4 q = vec4(p, 1.0);
	vec2 uv = vec2(dot(f.row_u, q), dot(f.row_v, q));
	if (!(uv.x >= 0.0 && uv.x <= 1.0 && uv.y >= 0.0 && uv.y <= 1.0))
		return 0.0;
	float dp = dot(f.row_depth, q);
	vec4 t = sky_read_2d(map, uv, false, 1.0);
	if (dp > t.w + f.bias.x)
		return SKYCLOUD_SHADOW_OPAQUE;
	return min(t.y * max(dp - t.x, 0.0), t.z);
}

// The light's transmittance at p (a ground point, or any).
float skycloud_shadow(sampler2D map, SkycloudShadowFrame f, vec3 p)
{
	return exp(-skycloud_shadow_depth(map, f, p));
}

// skycloud_march_sphere: the stable roots.
bool skycloud_march_sphere(float rb_km, float h_km, vec3 o, vec3 d, out float t0, out float t1)
{
	float b = o.x * d.x + o.y * d.y + (o.z + rb_km) * d.z;
	float cc = o.x * o.x + o.y * o.y + (o.z - h_km) * (o.z + h_km + 2.0 * rb_km);
	float disc = b * b - cc;
	t0 = 0.0;
	t1 = 0.0;
	if (disc < 0.0)
		return false;
	float q = b > 0.0 ? -(b + sqrt(disc)) : -b + sqrt(disc);
	float r = q != 0.0 ? cc / q : 0.0;
	t0 = min(q, r);
	t1 = max(q, r);
	return true;
}

// skycloud_march_span: the near piece of the ray between the lowest base
// and the highest top, in [0, max_km], never past the ground.
bool skycloud_march_span(SkycloudLayer layers[SKYCLOUD_MAX_LAYERS], int n, float rb_km, vec3 o, vec3 d,
			 float max_km, out float t0, out float t1)
{
	float lo = 1e30, hi = -1e30, a0, a1, b0, b1;
	t0 = 0.0;
	t1 = 0.0;
	for (int i = 0; i < n; i++) {
		if (!(layers[i].cover > 0.0))
			continue;
		lo = min(lo, layers[i].base_km);
		hi = max(hi, layers[i].top_km);
	}
	if (!(hi > lo) || !skycloud_march_sphere(rb_km, hi, o, d, a0, a1))
		return false;
	t0 = max(a0, 0.0);
	t1 = min(a1, max_km);
	if (skycloud_march_sphere(rb_km, 0.0, o, d, b0, b1) && b1 > 0.0)
		t1 = min(b0, t1);
	if (skycloud_march_sphere(rb_km, lo, o, d, b0, b1) && b1 > 0.0) {
		if (b0 > t0)
			t1 = min(b0, t1);
		else
			t0 = max(b1, t0);
	}
	return t1 > t0;
}

// skycloud_density_cov: the density with the coverage c0 from a table.
float skycloud_density_cov(SkycloudLayer L, float c0, float x, float y, float h, vec2 offset_km)
{
	float hf = (h - L.base_km) * L.inv_thickness_per_km;
	if (!(hf > 0.0 && hf < 1.0) || !(c0 > 0.0))
		return 0.0;
	float c = skycloud_saturate(c0 + L.anvil * hf * hf);
	float e = c * skycloud_profile(L, hf);
	if (!(e > 0.0))
		return 0.0;
	float px = skycloud_wrap(x - offset_km.x), py = skycloud_wrap(y - offset_km.y);
	float dn = skycloud_detail(L, px, py, skycloud_wrap(h));
	float f = skycloud_saturate((e - L.erosion * dn) * L.inv_keep);
	return L.extinction_per_km * min(f, e);
}

// Each layer's extinction per km at p, altitude h_km (sigma), and their sum.
float skycloud_march_density(SkycloudLayer layers[SKYCLOUD_MAX_LAYERS], SkycloudScene sc, sampler2D coverage,
			     vec3 p, float h_km, out vec4 sigma)
{
	int n = int(sc.field.z);
	vec4 cov = vec4(0.0);
	bool table = sc.field.w > 0.0;
	if (table) {
		vec2 uv = skycloud_table_uv(sc.field.w, p.xy - sc.table.xy);
		if (uv.x >= 0.0 && uv.x <= 1.0 && uv.y >= 0.0 && uv.y <= 1.0)
			cov = sky_read_2d(coverage, uv, false, 1.0);
	}
	sigma = vec4(0.0);
	float sum = 0.0;
	for (int i = 0; i < n; i++) {
		SkycloudLayer L = layers[i];
		float s = table ? skycloud_density_cov(L, cov[L.index & 3u], p.x, p.y, h_km, sc.field.xy)
				: skycloud_density(L, p.x, p.y, h_km, sc.field.xy);
		sigma[i] = s;
		sum += s;
	}
	return sum;
}

float skycloud_hg(float g, float mu)
{
	float den = 1.0 + g * g - 2.0 * g * mu;
	return (1.0 - g * g) / (4.0 * SKYMAP_PI * den * sqrt(den));
}

// The light's transmittance through the air to altitude h_km with its
// cos-zenith mu there: 0 below the horizon.
vec3 skycloud_air_transmittance(SkyState s, sampler2D transmittance, float h_km, float mu)
{
	if (mu < skymap_horizon_cos(s.planet.x, max(h_km, 0.0)))
		return vec3(0.0);
	return sky_transmittance(s, transmittance, h_km, mu);
}

// skycloud_light_march: the layers' optical depth from p along l.
float skycloud_light_march(SkycloudLayer layers[SKYCLOUD_MAX_LAYERS], SkycloudScene sc, sampler2D coverage,
			   float rb_km, vec3 p, vec3 l, int steps)
{
	float t0, t1, tau = 0.0;
	if (steps < 1 || !skycloud_march_span(layers, int(sc.field.z), rb_km, p, l, 1e30, t0, t1))
		return 0.0;
	float dt = (t1 - t0) / float(steps);
	for (int k = 0; k < steps; k++) {
		vec3 q = p + (t0 + (float(k) + 0.5) * dt) * l;
		vec4 sigma;
		tau += skycloud_march_density(layers, sc, coverage, q, skycloud_altitude(rb_km, q), sigma);
	}
	return tau * dt;
}

// The light's optical depth through the clouds from p: its shadow map's,
// or light_steps steps of skycloud_light_march.
float skycloud_light_depth(SkycloudLayer layers[SKYCLOUD_MAX_LAYERS], SkycloudScene sc, SkycloudLight li,
			   sampler2D coverage, sampler2D shadow, float rb_km, vec3 p, int light_steps)
{
	if (light_steps > 0)
		return skycloud_light_march(layers, sc, coverage, rb_km, p, li.dir.xyz, light_steps);
	return li.dir.w > 0.5 ? skycloud_shadow_depth(shadow, li.frame, p) : 0.0;
}

// skycloud_slab_transmittance: a conservative slab's share of a beam at
// cosine mu0 > 0 let through, direct and scattered (Eddington two-stream).
float skycloud_slab_transmittance(float tau, float g, float mu0)
{
	return (2.0 / 3.0 + mu0 + (2.0 / 3.0 - mu0) * exp(-tau / mu0)) / (4.0 / 3.0 + (1.0 - g) * tau);
}

// skycloud_slab_diffuse: the same under a uniform sky (two-point Gauss).
float skycloud_slab_diffuse(float tau, float g)
{
	const float m0 = 0.21132486540518713, m1 = 0.7886751345948129;
	return m0 * skycloud_slab_transmittance(tau, g, m0) + m1 * skycloud_slab_transmittance(tau, g, m1);
}

// skycloud_diffuse: the light diffused inside layer L at h_km per unit of
// its scattering and of the light through the air (tau toward the light
// at cosine mu_l; mu_v the view's cosine to the local up).
float skycloud_diffuse(SkycloudLayer L, float g, float h_km, float tau, float mu_l, float mu_v)
{
	if (!(mu_l > 0.0) || !(tau < SKYCLOUD_SHADOW_OPAQUE))
		return 0.0;
	float tau_z = tau * mu_l, beam = exp(-tau / mu_l);
	float below = clamp((h_km - L.base_km) * L.inv_thickness_per_km, 0.0, 1.0);
	float tau_b = L.extinction_per_km * (L.top_km - L.base_km) * below * L.profile_integral;
	float fd = skycloud_slab_transmittance(tau_z, g, mu_l) - beam;
	float fu = (1.0 - skycloud_slab_diffuse(tau_b, g)) * (fd + beam);
	return mu_l * (fd * (1.0 + mu_v) + fu * (1.0 - mu_v)) / (2.0 * SKYMAP_PI);
}

// skycloud_march_source: the source at p per unit of extinction, summed
// over the layers' extinctions sigma; mu = view . light, mu_v the view's
// cosine to the local up (for the diffusion).
vec3 skycloud_march_source(SkyState s, sampler2D transmittance, sampler2D multiscatter, sampler2D coverage,
			   sampler2D shadow,
			   SkycloudLayer layers[SKYCLOUD_MAX_LAYERS], SkycloudScene sc, SkycloudLight li, vec3 p,
			   float h_km, vec4 sigma, float mu, float mu_v, int light_steps)
{
	float rb = s.planet.x;
	vec3 c = vec3(p.xy, p.z + rb);
	float mu_l = dot(c, li.dir.xyz) / length(c);
	vec3 tr = skycloud_air_transmittance(s, transmittance, h_km, mu_l);
	float tau = tr.r + tr.g + tr.b > 0.0 ? skycloud_light_depth(layers, sc, li, coverage, shadow, rb, p, light_steps) : 0.0;
	float direct = 0.0, scatter = 0.0;
	bool diffusion = sc.ambient.w > 0.5;
	int n = int(sc.field.z), octaves = diffusion ? 1 : int(sc.octaves.x);
	for (int i = 0; i < n; i++) {
		float sg = sc.albedo[i] * sigma[i];
		if (!(sg > 0.0))
			continue;
		float bk = 1.0, ak = 1.0, ck = 1.0, lobes = 0.0;
		for (int k = 0; k < octaves; k++) {
			lobes += bk * exp(-ak * tau) * skycloud_hg(ck * sc.phase_g[i], mu);
			bk *= sc.octaves.z;
			ak *= sc.octaves.y;
			ck *= sc.octaves.w;
		}
		if (diffusion)
			lobes += skycloud_diffuse(layers[i], sc.phase_g[i], h_km, tau, mu_l, mu_v);
		direct += sg * lobes;
		scatter += sg;
	}
	vec3 ms = sky_multiscatter(s, multiscatter, h_km, mu_l).rgb;
	float open = 1.0 - skycloud_sky_occlusion(layers, n, h_km);
	return li.illuminance.rgb * (tr * direct + scatter * open * ms) + scatter * open * sc.ambient.rgb / SKYMAP_PI;
}

// The clouds along the view ray o + t d, t in [0, max_km], lit by one
// light: skycloud_march (steps over the span, sample k at t0 + (k +
// jitter) dt, each step integrated exactly for its extinction and source).
SkycloudSample skycloud_march(SkyState s, sampler2D transmittance, sampler2D multiscatter, sampler2D coverage,
			      sampler2D shadow, SkycloudLayer layers[SKYCLOUD_MAX_LAYERS], SkycloudScene sc,
			      SkycloudLight li, vec3 o, vec3 d, float max_km, int steps, int light_steps,
			      float jitter)
{
	SkycloudSample r = SkycloudSample(vec3(0.0), 1.0, max_km);
	float t0, t1;
	float rb = s.planet.x;
	if (steps < 1 || !skycloud_march_span(layers, int(sc.field.z), rb, o, d, max_km, t0, t1))
		return r;
	float dt = (t1 - t0) / float(steps), T = 1.0, wsum = 0.0, tsum = 0.0;
	float mu = dot(d, li.dir.xyz);
	for (int k = 0; k < steps && T > SKYCLOUD_MARCH_MIN_TRANSMITTANCE; k++) {
		float t = t0 + (float(k) + jitter) * dt;
		vec3 p = o + t * d;
		float h = skycloud_altitude(rb, p);
		vec4 sigma;
		float sg = skycloud_march_density(layers, sc, coverage, p, h, sigma);
		if (!(sg > 0.0))
			continue;
		vec3 cp = vec3(p.xy, p.z + rb);
		float up = dot(cp, d) / length(cp);
		vec3 src = skycloud_march_source(s, transmittance, multiscatter, coverage, shadow, layers, sc, li, p,
						 h, sigma, mu, up, light_steps);
		float dT = exp(-sg * dt), w = T * (1.0 - dT);
		r.radiance += w * src / sg;
		wsum += w;
		tsum += w * t;
		T *= dT;
	}
	r.transmittance = T;
	if (wsum > 0.0)
		r.depth_km = tsum / wsum;
	return r;
}

// skycloud_ground_light: the ground's light at altitude h_km under the
// layers as shares of the clear sky's: x of the sky's irradiance, y of a
// light's horizontal irradiance at cosine mu_l scattered down through the
// layers (its beam is the shadow map's).
vec2 skycloud_ground_light(SkycloudLayer layers[SKYCLOUD_MAX_LAYERS], SkycloudScene sc, float h_km, float mu_l)
{
	float sky = 1.0, through = 1.0, beam = 1.0;
	int n = int(sc.field.z);
	for (int i = 0; i < n; i++) {
		SkycloudLayer L = layers[i];
		float above = clamp((L.top_km - h_km) * L.inv_thickness_per_km, 0.0, 1.0);
		float tau = L.extinction_per_km * (L.top_km - L.base_km) * above * L.profile_integral;
		float c = L.cover;
		sky *= 1.0 - c + c * skycloud_slab_diffuse(tau, sc.phase_g[i]);
		if (mu_l > 0.0) {
			through *= 1.0 - c + c * skycloud_slab_transmittance(tau, sc.phase_g[i], mu_l);
			beam *= 1.0 - c + c * exp(-tau / mu_l);
		}
	}
	return vec2(sky, mu_l > 0.0 ? through - beam : 0.0);
}

// A pixel's radiance with the clouds c in front of behind (the sky with
// its disks, or a surface with its own aerial perspective) and the air's
// aerial perspective at the clouds' depth (air: rgb in-scattered, a its
// transmittance): skycloud_composite.
vec3 skycloud_composite(vec3 behind, SkycloudSample c, vec4 air)
{
	return c.transmittance * behind + (1.0 - c.transmittance) * air.rgb + air.a * c.radiance;
}

#endif
