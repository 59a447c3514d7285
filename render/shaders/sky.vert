#version 450
// sky.vert - one triangle over the whole tile at the far depth (0, reversed),
// so that the sky fills what the terrain left.
void main()
{
	vec2 p = vec2((gl_VertexIndex << 1) & 2, gl_VertexIndex & 2);
	gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
