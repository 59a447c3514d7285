// terrain.glsl - the terrain height field at BINDING_TERRAIN as
// proto/skyterrain.h's skyterrain_height_km reads it: the same texels,
// bilinear between their centres, the edge texels' value out to the
// square's edge, 0 outside it. Included after clouds.glsl (the block's
// TERRAIN_* lanes); read only where TERRAIN_HALF_KM > 0.

layout(std430, binding = BINDING_TERRAIN) readonly buffer TerrainTexels { uint d[]; } TR;

// Texel (i, j) (west to east, north to south), clamped into the field.
float terrain_texel(int i, int j, int w, int h)
{
	int k = clamp(j, 0, h - 1) * w + clamp(i, 0, w - 1);
	return float((TR.d[k >> 1] >> (16 * (k & 1))) & 0xffffu);
}

// Height in km at field coordinates (x east, y north) km.
float terrain_height_km(float x, float y)
{
	float half_km = CL.TERRAIN_HALF_KM;
	if (!(x >= -half_km && x <= half_km && y >= -half_km && y <= half_km))
		return 0.0;
	int w = int(CL.TERRAIN_WIDTH_TEXELS), h = int(CL.TERRAIN_HEIGHT_TEXELS);
	float u = (x + half_km) * (float(w) / (2.0 * half_km)) - 0.5;
	float v = (half_km - y) * (float(h) / (2.0 * half_km)) - 0.5;
	float u0 = floor(u), v0 = floor(v), fu = u - u0, fv = v - v0;
	int i = int(u0), j = int(v0);
	float a = terrain_texel(i, j, w, h), b = terrain_texel(i + 1, j, w, h);
	float c = terrain_texel(i, j + 1, w, h), e = terrain_texel(i + 1, j + 1, w, h);
	float top = a + fu * (b - a), bottom = c + fu * (e - c);
	return CL.TERRAIN_KM_PER_UNIT * (top + fv * (bottom - top));
}

// How far p is above the terrain (< 0: inside it).
float terrain_clearance_km(float rb_km, vec3 p)
{
	return skycloud_altitude(rb_km, p) - terrain_height_km(p.x, p.y);
}
