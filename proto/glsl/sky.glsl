// sky.glsl - the GLSL library of render clients: reads skyd's tables as skyd
// lays them out and gives the sky for a view direction, the transmittance
// toward the sun and the moon, their disks and aerial perspective, as
// libsky's CPU sampling (proto/skysample.h) gives them.
//
// Use (docs/render-clients.md walks through a whole client):
//
//     #extension GL_GOOGLE_include_directive : require   // or paste the files
//     #include "sky.glsl"                                // includes skymap.glsl
//     layout(std140, binding = 0) uniform SkyBlock { SkyState sky; };
//     layout(binding = 1) uniform sampler2D transmittance_tex;
//     layout(binding = 2) uniform sampler2D skyview_tex;
//     layout(binding = 3) uniform sampler3D aerial_tex;
//     ...
//     vec3 L = sky_radiance(sky, skyview_tex, dir)
//            + sky_disks(sky, transmittance_tex, dir, SKY_DISK_SUN | SKY_DISK_MOON);
//     vec3 lit = sky_apply_aerial(sky, aerial_tex, screen_uv, distance_km, surface);
//
// Every name the library defines starts with sky_, Sky, SKY_ or skymap_:
// keep the client's own names out of those prefixes.
//
// The client declares the textures (any set and binding, combined image
// samplers) and passes them to the functions, as Bruneton's reference code
// and engines' atmosphere libraries do: no binding is imposed, and the
// same functions serve bindless arrays. SkyState is struct sky_gpu_state of
// sky.h, filled by sky_gpu_state() from a slot: upload it with the tables
// of the same generation.
//
// Textures: one image per table, the table's format (sky_gpu_tables():
// R32G32B32A32_SFLOAT or R16G16B16A16_SFLOAT), its width, height (and depth
// for the aerial volume), the texels copied as they are in the slot (row 0
// of the image is the table's row 0: v runs bottom-up in the table and
// upward in the image's t, so nothing flips). Samplers: linear filtering,
// no mipmaps, CLAMP_TO_EDGE on every axis except the sky-view table's u,
// which is REPEAT (azimuth is periodic).
//
// Filtering: by default the texture units filter (texture()). They weigh
// texels with 8 bits of sub-texel position on many GPUs, so a result may
// differ from libsky's double bilinear by about 1/256 of the difference
// between neighbouring texels, and some (an NVIDIA H100) return a float16
// table's filtered value as a binary16, 2^-11 of it more (test_glsl_sample
// bounds both; lavapipe weighs float formats in float).
// Define SKY_GLSL_EXACT_FILTER before including to filter in the shader
// instead (texelFetch and mix in float, 4 fetches a 2-D lookup, 8 for the
// aerial volume): then the results agree with libsky to float rounding.
// GLSL 4.50 (Vulkan or OpenGL 4.5), no extension.
#ifndef SKY_GLSL
#define SKY_GLSL

#include "skymap.glsl"

// The per-generation uniforms, std140 and std430 alike (vec4s only): struct
// sky_gpu_state of sky.h, field for field, from the slot's struct
// sky_shm_state. Directions are unit vectors in the observer's
// east-north-up frame (x east, y north, z up).
struct SkyState {
	vec4 sun;		// xyz: sun_direction; w: sun_angular_radius_rad
	vec4 sun_illuminance;	// rgb: sun_illuminance_lx at the top of the atmosphere
	vec4 moon;		// xyz: moon_direction; w: moon_angular_radius_rad
	vec4 moon_illuminance;	// rgb: moon_illuminance_lx (0 when the moon lights nothing)
	vec4 planet;		// x: bottom_radius_km, y: top_radius_km, z: altitude_km (the observer), w: 0
	vec4 horizon;		// the geometric horizon at the observer, in double on the CPU:
				// x: skymap_horizon_cos, y: the sine, z: the zenith angle (rad), w: 0
	vec4 rgb_scale;		// by table id: 2^rgb_scale_log2[id] (1 for float32 tables)
	vec4 aerial;		// x: aerial_range_km, y: aerial_squared (1 or 0),
				// z: tan(camera_vfov_rad / 2), w: camera_aspect
	vec4 camera_forward;	// xyz: the aerial volume's camera (the state's or a view's)
	vec4 camera_right;
	vec4 camera_up;		// w: that camera's altitude_km
	vec4 panorama;		// a view of form panorama (struct sky_shm_panorama): x: azimuth0_rad,
				// y: azimuth_step_rad, z: row0, w: row_step; 0 for a volume
	vec4 panorama_grid;	// x: horizon_rad, y: width, z: height, w: the aerial texture's form:
				// 0 a volume, 1 a panorama of an arc, 2 a panorama of the full circle
};

// enum sky_shm_table_id.
const int SKY_TABLE_TRANSMITTANCE = 0;
const int SKY_TABLE_MULTISCATTER = 1;
const int SKY_TABLE_SKYVIEW = 2;
const int SKY_TABLE_AERIAL = 3;

// sky_disks() flags: enum sky_sample_flags of sky.h.
const int SKY_DISK_SUN = 1;
const int SKY_DISK_MOON = 2;
const int SKY_DISK_LIMB_DARKENING = 4;
// The linear limb-darkening coefficient libsky uses (sky_render.c).
const float SKY_LIMB_U = 0.6;

// ---- Reading a table -----------------------------------------------------

#ifdef SKY_GLSL_EXACT_FILTER
// skysample_axis: the two texels of coordinate u on an axis of n and the
// weight of the second; periodic where wrap.
ivec3 sky_axis_(float u, int n, bool wrap, out float ret_f)
{
	float x = u * float(n) - 0.5, fl = floor(x);
	ret_f = x - fl;
	int i0 = int(fl);
	if (wrap) {
		// fl mod n (GLSL's % is undefined for negative operands).
		i0 = int(fl - float(n) * floor(fl / float(n)));
		return ivec3(i0, i0 + 1 < n ? i0 + 1 : 0, 0);
	}
	if (fl < 0.0 || fl >= float(n - 1)) {
		ret_f = 0.0;
		i0 = fl < 0.0 ? 0 : n - 1;
		return ivec3(i0, i0, 0);
	}
	return ivec3(i0, i0 + 1, 0);
}

vec4 sky_bilinear_(sampler2D t, vec2 uv, bool wrap_u)
{
	ivec2 n = textureSize(t, 0);
	float fu, fv;
	ivec3 i = sky_axis_(uv.x, n.x, wrap_u, fu), j = sky_axis_(uv.y, n.y, false, fv);
	vec4 lo = mix(texelFetch(t, ivec2(i.x, j.x), 0), texelFetch(t, ivec2(i.y, j.x), 0), fu);
	vec4 hi = mix(texelFetch(t, ivec2(i.x, j.y), 0), texelFetch(t, ivec2(i.y, j.y), 0), fu);
	return mix(lo, hi, fv);
}

vec4 sky_slice_(sampler3D t, vec2 uv, int k)
{
	ivec3 n = textureSize(t, 0);
	float fu, fv;
	ivec3 i = sky_axis_(uv.x, n.x, false, fu), j = sky_axis_(uv.y, n.y, false, fv);
	vec4 lo = mix(texelFetch(t, ivec3(i.x, j.x, k), 0), texelFetch(t, ivec3(i.y, j.x, k), 0), fu);
	vec4 hi = mix(texelFetch(t, ivec3(i.x, j.y, k), 0), texelFetch(t, ivec3(i.y, j.y, k), 0), fu);
	return mix(lo, hi, fv);
}
#endif

// A table's RGBA at uv (the texel centres at (i + 0.5) / n), its RGB times
// the table's scale. wrap_u: the sky-view table's periodic azimuth (the
// hardware path relies on the sampler's REPEAT for it).
vec4 sky_read_2d(sampler2D t, vec2 uv, bool wrap_u, float rgb_scale)
{
#ifdef SKY_GLSL_EXACT_FILTER
	vec4 p = sky_bilinear_(t, uv, wrap_u);
#else
	vec4 p = texture(t, uv);
#endif
	return vec4(p.rgb * rgb_scale, p.a);
}

// The aerial volume at screen uv and continuous slice w (skymap_aerial_slice):
// linear between slices, from (0, 0, 0, 1) at the camera (w = -1) to slice
// 0, the last slice beyond it; RGB scaled.
vec4 sky_read_aerial(sampler3D t, vec2 uv, float w, float rgb_scale)
{
	int d = textureSize(t, 0).z;
	float wc = clamp(w, 0.0, float(d - 1));
#ifdef SKY_GLSL_EXACT_FILTER
	int k = int(floor(wc));
	int k1 = min(k + 1, d - 1);
	vec4 p = mix(sky_slice_(t, uv, k), sky_slice_(t, uv, k1), wc - float(k));
#else
	vec4 p = texture(t, vec3(uv, (wc + 0.5) / float(d)));
#endif
	p.rgb *= rgb_scale;
	// Between the camera and slice 0 (w in [-1, 0]): toward (L = 0, T = 1).
	return w < 0.0 ? mix(vec4(0.0, 0.0, 0.0, 1.0), p, max(w + 1.0, 0.0)) : p;
}

// ---- Transmittance ---------------------------------------------------------

// Transmittance (RGB, [0, 1]) from altitude_km to the top of the atmosphere
// along cos-zenith mu, for a ray that does not meet the ground (below the
// horizon: the horizon's value). skysample_transmittance.
vec3 sky_transmittance(SkyState s, sampler2D transmittance, float altitude_km, float mu)
{
	ivec2 n = textureSize(transmittance, 0);
	vec2 uv = skymap_transmittance_uv(s.planet.x, s.planet.y, altitude_km, mu, n.x, n.y);
	return sky_read_2d(transmittance, uv, false, s.rgb_scale[SKY_TABLE_TRANSMITTANCE]).rgb;
}

// Transmittance from the observer toward a light in direction dir (unit,
// ENU): 0 below the geometric horizon. skysample_light_transmittance.
vec3 sky_light_transmittance(SkyState s, sampler2D transmittance, vec3 dir)
{
	if (dir.z < s.horizon.x)
		return vec3(0.0);
	return sky_transmittance(s, transmittance, s.planet.z, dir.z);
}

// The sun's (moon's) illuminance at the observer on a surface facing it, lx
// per channel: top-of-atmosphere illuminance times the transmittance.
vec3 sky_sun_illuminance(SkyState s, sampler2D transmittance)
{
	return s.sun_illuminance.rgb * sky_light_transmittance(s, transmittance, s.sun.xyz);
}

vec3 sky_moon_illuminance(SkyState s, sampler2D transmittance)
{
	return s.moon_illuminance.rgb * sky_light_transmittance(s, transmittance, s.moon.xyz);
}

// ---- Sky -------------------------------------------------------------------

// Sky radiance (RGB, cd/m2 per channel) toward the unit ENU direction dir,
// from the sky-view table: no disk (sky_disks). Below the horizon it is the
// ground as the table holds it. skysample_sky.
vec3 sky_radiance(SkyState s, sampler2D skyview, vec3 dir)
{
	vec2 uv = skymap_skyview_uv_dir(s.horizon.x, s.horizon.y, s.horizon.z, dir, textureSize(skyview, 0).y);
	return sky_read_2d(skyview, uv, true, s.rgb_scale[SKY_TABLE_SKYVIEW]).rgb;
}

// Radiance of one light's disk of angular radius radius_rad seen along
// view: illuminance / (pi r^2) times the transmittance toward the light,
// with the linear limb law of coefficient limb_u (0: none) normalised to
// keep the illuminance. skysample_add_disk; the angle from the centre is
// taken from the chord and the cross product, which keep their bits for a
// disk of a quarter degree where a dot product near 1 does not.
vec3 sky_disk(SkyState s, sampler2D transmittance, vec3 light_dir, float radius_rad,
	      vec3 illuminance, vec3 view, float limb_u)
{
	if (!(radius_rad > 0.0) || length(view - light_dir) > 2.0 * sin(0.5 * radius_rad))
		return vec3(0.0);
	vec3 tr = sky_light_transmittance(s, transmittance, light_dir);
	float limb = 1.0;
	if (limb_u > 0.0) {
		float x = min(length(cross(view, light_dir)) / sin(radius_rad), 1.0);
		float m = sqrt(1.0 - x * x);
		limb = (1.0 - limb_u * (1.0 - m)) / (1.0 - limb_u / 3.0);
	}
	return illuminance / (SKYMAP_PI * radius_rad * radius_rad) * tr * limb;
}

// The disks in flags (SKY_DISK_*) seen along view, to add to sky_radiance:
// sky_sample_sky's disks (limb darkening on the sun only, u = SKY_LIMB_U).
vec3 sky_disks(SkyState s, sampler2D transmittance, vec3 view, int flags)
{
	vec3 l = vec3(0.0);
	if ((flags & SKY_DISK_SUN) != 0)
		l += sky_disk(s, transmittance, s.sun.xyz, s.sun.w, s.sun_illuminance.rgb, view,
			      (flags & SKY_DISK_LIMB_DARKENING) != 0 ? SKY_LIMB_U : 0.0);
	if ((flags & SKY_DISK_MOON) != 0)
		l += sky_disk(s, transmittance, s.moon.xyz, s.moon.w, s.moon_illuminance.rgb, view, 0.0);
	return l;
}

// ---- Multi-scattering ------------------------------------------------------

// The multi-scattering table at altitude_km for the light's cos-zenith mu_s
// (RGB psi_ms, A the ground's share; skymap.h), for a client that marches
// its own media (clouds, fog) lit by the same sky.
vec4 sky_multiscatter(SkyState s, sampler2D multiscatter, float altitude_km, float mu_s)
{
	ivec2 n = textureSize(multiscatter, 0);
	vec2 uv = skymap_multiscatter_uv(s.planet.x, s.planet.y, altitude_km, mu_s, n.x, n.y);
	return sky_read_2d(multiscatter, uv, false, s.rgb_scale[SKY_TABLE_MULTISCATTER]);
}

// ---- Aerial perspective ----------------------------------------------------

// Screen position (u right, v up, [0, 1] inside the frustum) of the unit ENU
// direction dir in the aerial volume's camera; off-screen directions get
// positions outside [0, 1], which the sampler clamps to the border froxels.
vec2 sky_aerial_screen_uv(SkyState s, vec3 dir)
{
	float z = max(dot(dir, s.camera_forward.xyz), 1e-6);
	vec2 ndc = vec2(dot(dir, s.camera_right.xyz) / (s.aerial.z * s.aerial.w),
			dot(dir, s.camera_up.xyz) / s.aerial.z) / z;
	return 0.5 + 0.5 * ndc;
}

// Aerial perspective at screen position screen_uv, distance_km along the
// view ray: RGB in-scattered radiance (cd/m2), A the mean transmittance.
// skysample_aerial.
vec4 sky_aerial(SkyState s, sampler3D aerial, vec2 screen_uv, float distance_km)
{
	int d = textureSize(aerial, 0).z;
	float w = skymap_aerial_slice(distance_km, d, s.aerial.x, s.aerial.y > 0.5);
	return sky_read_aerial(aerial, screen_uv, w, s.rgb_scale[SKY_TABLE_AERIAL]);
}

// A surface's radiance seen through the air at distance_km: L T + in-scattered.
vec3 sky_apply_aerial(SkyState s, sampler3D aerial, vec2 screen_uv, float distance_km, vec3 surface)
{
	vec4 a = sky_aerial(s, aerial, screen_uv, distance_km);
	return surface * a.a + a.rgb;
}

// Aerial perspective toward dir (unit, in the east-north-up frame of the
// aerial camera's eye: the observer's, or a view's own) at distance_km,
// whatever the form of the aerial texture: a volume through its camera's
// screen position, a panorama (a view of form panorama: RGB stored as the
// logarithm of the radiance) through its column and row. In a panorama,
// the logarithm is filtered in all three axes (one trilinear fetch), then
// the radiance before slice 0 is linear toward the eye as in a volume.
// skysample_panorama.
vec4 sky_aerial_dir(SkyState s, sampler3D aerial, vec3 dir, float distance_km)
{
	if (s.panorama_grid.w < 0.5)
		return sky_aerial(s, aerial, sky_aerial_screen_uv(s, dir), distance_km);
	int d = textureSize(aerial, 0).z;
	float w = skymap_aerial_slice(distance_km, d, s.aerial.x, s.aerial.y > 0.5);
	vec2 uv = skymap_panorama_uv(s.panorama.x, s.panorama.y, s.panorama.z, s.panorama.w,
				     s.panorama_grid.x, int(s.panorama_grid.y), int(s.panorama_grid.z),
				     s.panorama_grid.w > 1.5, atan(dir.x, dir.y),
				     asin(clamp(dir.z, -1.0, 1.0)));
	vec4 p = sky_read_aerial(aerial, uv, max(w, 0.0), 1.0);
	p.rgb = exp(p.rgb);
	return w < 0.0 ? mix(vec4(0.0, 0.0, 0.0, 1.0), p, max(w + 1.0, 0.0)) : p;
}

// A surface's radiance seen through the air toward dir at distance_km.
vec3 sky_apply_aerial_dir(SkyState s, sampler3D aerial, vec3 dir, float distance_km, vec3 surface)
{
	vec4 a = sky_aerial_dir(s, aerial, dir, distance_km);
	return surface * a.a + a.rgb;
}

#endif
