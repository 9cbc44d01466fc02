#version 330 core
// servoface's replacement for pyrender's mesh.vert: same inputs and outputs, but normals are turned by
// mat3(M * inst_m) instead of the inverse-transpose computed per vertex (4x4 inverse per vertex is costly
// on a CPU rasteriser). Exact for the rigid transforms (rotation + translation) servoface draws with.

layout(location = 0) in vec3 position;
#ifdef NORMAL_LOC
layout(location = NORMAL_LOC) in vec3 normal;
#endif
#ifdef COLOR_0_LOC
layout(location = COLOR_0_LOC) in vec4 color_0;
#endif
layout(location = INST_M_LOC) in mat4 inst_m;

uniform mat4 M;
uniform mat4 V;
uniform mat4 P;

out vec3 frag_position;
#ifdef NORMAL_LOC
out vec3 frag_normal;
#endif
#ifdef COLOR_0_LOC
out vec4 color_multiplier;
#endif

void main()
{
    mat4 model = M * inst_m;
    vec4 world = model * vec4(position, 1.0);
    gl_Position = P * V * world;
    frag_position = vec3(world);
#ifdef NORMAL_LOC
    frag_normal = mat3(model) * normal;
#endif
#ifdef COLOR_0_LOC
    color_multiplier = color_0;
#endif
}
