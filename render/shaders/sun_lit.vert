#version 330 core
// deckpose's vertex shader for sun_lit.frag (render/sun_shader.py): pyrender's mesh.vert for the
// attributes the deck scene uses (position, normal, texture coordinates, vertex colour), plus the
// vertex's position in the sun's shadow-map space, so the fragment shader does not transform it.
layout(location = 0) in vec3 position;
#ifdef NORMAL_LOC
layout(location = NORMAL_LOC) in vec3 normal;
#endif
#ifdef TEXCOORD_0_LOC
layout(location = TEXCOORD_0_LOC) in vec2 texcoord_0;
#endif
#ifdef COLOR_0_LOC
layout(location = COLOR_0_LOC) in vec4 color_0;
#endif
layout(location = INST_M_LOC) in mat4 inst_m;

uniform mat4 M;
uniform mat4 V;
uniform mat4 P;
#ifdef DIRECTIONAL_LIGHT_SHADOWS
struct DirectionalLight {
    vec3 color;
    float intensity;
    vec3 direction;
    sampler2D shadow_map;
    mat4 light_matrix;
};
uniform DirectionalLight directional_lights[MAX_DIRECTIONAL_LIGHTS];
out vec4 light_position;
#endif

out vec3 frag_position;
#ifdef NORMAL_LOC
out vec3 frag_normal;
#endif
#ifdef TEXCOORD_0_LOC
out vec2 uv_0;
#endif
#ifdef COLOR_0_LOC
out vec4 color_multiplier;
#endif

void main()
{
    vec4 world = M * inst_m * vec4(position, 1.0);
    gl_Position = P * V * world;
    frag_position = vec3(world);
#ifdef DIRECTIONAL_LIGHT_SHADOWS
    light_position = directional_lights[0].light_matrix * world;
#endif
#ifdef NORMAL_LOC
    frag_normal = normalize(vec3(transpose(inverse(M * inst_m)) * vec4(normal, 0.0)));
#endif
#ifdef TEXCOORD_0_LOC
    uv_0 = texcoord_0;
#endif
#ifdef COLOR_0_LOC
    color_multiplier = color_0;
#endif
}
