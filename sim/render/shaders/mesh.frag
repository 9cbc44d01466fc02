#version 330 core
// servoface's replacement for pyrender's PBR mesh.frag: wrapped Lambert + normalised Blinn-Phong per
// directional light (specular from the key light only = the brightest; pyrender's light order is a set's
// order, so the key is found by intensity, see sim/render/camera.py LIGHTS), ambient,
// optional vertex colours, gamma out. About half the per-pixel cost of the
// GGX shader on llvmpipe, and a softer, more skin-like falloff. Uniform names are pyrender's, so pyrender's
// renderer sets them unchanged (uniforms it sets that are not used here are ignored by pyrender).

const float PI = 3.141592653589793;
const float WRAP = 0.25;  // light wraps a little past the terminator (cheap subsurface look)

struct DirectionalLight {
    vec3 color;
    float intensity;
    vec3 direction;
};

struct Material {
    vec3 emissive_factor;
    vec4 base_color_factor;
    float metallic_factor;
    float roughness_factor;
};

uniform Material material;
uniform DirectionalLight directional_lights[MAX_DIRECTIONAL_LIGHTS];
uniform int n_directional_lights;
uniform vec3 cam_pos;
uniform vec3 ambient_light;

in vec3 frag_position;
#ifdef NORMAL_LOC
in vec3 frag_normal;
#endif
#ifdef COLOR_0_LOC
in vec4 color_multiplier;
#endif

out vec4 frag_color;

void main()
{
    vec4 base = material.base_color_factor;
#ifdef COLOR_0_LOC
    base *= color_multiplier;
#endif
#ifdef NORMAL_LOC
    // two-sided lighting: a back face seen (open, double-sided meshes) is lit as its other side
    vec3 n = gl_FrontFacing ? normalize(frag_normal) : -normalize(frag_normal);
#else
    vec3 n = normalize(cross(dFdx(frag_position), dFdy(frag_position)));
#endif
    vec3 v = normalize(cam_pos - frag_position);
    float rough = clamp(material.roughness_factor, 0.05, 1.0);
    float shininess = 2.0 / (rough * rough * rough * rough) - 2.0;
    float spec_scale = 0.04 * (shininess + 8.0) / (8.0 * PI);
    vec3 diffuse = base.rgb / PI;
    vec3 color = base.rgb * ambient_light;
    int key = 0;
    for (int i = 0; i < n_directional_lights; i++) {
        if (directional_lights[i].intensity > directional_lights[key].intensity) key = i;
        vec3 l = -directional_lights[i].direction;
        float nl = max((dot(n, l) + WRAP) / (1.0 + WRAP), 0.0);
        color += directional_lights[i].color * directional_lights[i].intensity * diffuse * nl;
    }
    if (n_directional_lights > 0) {
        vec3 l = -directional_lights[key].direction;
        float nl_raw = dot(n, l);
        if (nl_raw > 0.0) {
            vec3 h = normalize(l + v);
            float spec = pow(max(dot(n, h), 0.0), shininess) * spec_scale * nl_raw;
            color += directional_lights[key].color * directional_lights[key].intensity * spec;
        }
    }
    color += material.emissive_factor;
    frag_color = clamp(vec4(pow(color, vec3(1.0 / 2.2)), base.a), 0.0, 1.0);
}
