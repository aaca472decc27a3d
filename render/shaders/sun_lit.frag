#version 330 core
// deckpose's lean metallic-roughness shader (render/sun_shader.py): the scene's one directional
// light (the sun) and its ambient light, with pyrender's Cook-Torrance terms (pyrender/shaders/
// mesh.frag), and a 4-texel bilinear shadow test in place of pyrender's 36-texel PCF
// that calls a point beyond the shadow map lit (pyrender's wraps around the map, REPEAT). Point and
// spot lights, directional lights after the first, normal, occlusion, emissive and metallic-roughness
// textures and glossy materials are not drawn (the deck scene has none).
struct DirectionalLight {
    vec3 color;
    float intensity;
    vec3 direction;
#ifdef DIRECTIONAL_LIGHT_SHADOWS
    sampler2D shadow_map;
    mat4 light_matrix;
#endif
};
struct Material {
    vec3 emissive_factor;
    vec4 base_color_factor;
    float metallic_factor;
    float roughness_factor;
#ifdef HAS_BASE_COLOR_TEX
    sampler2D base_color_texture;
#endif
};
uniform Material material;
uniform DirectionalLight directional_lights[MAX_DIRECTIONAL_LIGHTS];
uniform int n_directional_lights;
uniform vec3 cam_pos;
uniform vec3 ambient_light;

in vec3 frag_position;
#ifdef DIRECTIONAL_LIGHT_SHADOWS
in vec4 light_position;  // in the sun's shadow-map space (sun_lit.vert)
#endif
#ifdef NORMAL_LOC
in vec3 frag_normal;
#endif
#ifdef TEXCOORD_0_LOC
in vec2 uv_0;
#endif
#ifdef COLOR_0_LOC
in vec4 color_multiplier;
#endif
out vec4 frag_color;

const float PI = 3.141592653589793;
const float min_roughness = 0.04;

vec3 srgb_to_linear(vec3 c)
{
    return mix(c / 12.92, pow((c + 0.055) / 1.055, vec3(2.4)), step(vec3(0.04045), c));
}

#ifdef DIRECTIONAL_LIGHT_SHADOWS
float lit_fraction(sampler2D shadow_map, float nl)
{
    vec4 p = light_position;
    vec3 c = p.xyz / p.w * 0.5 + 0.5;
    if (c.z > 1.0 || any(lessThan(c.xy, vec2(0.0))) || any(greaterThan(c.xy, vec2(1.0)))) {
        return 1.0;  // beyond the shadow map (render/scene.py frames the ship, shadow_frame_m): lit
    }
    float compare = c.z - max(0.001 * (1.0 - nl), 0.0001) / p.w;
    vec2 size = vec2(textureSize(shadow_map, 0));
    vec2 t = c.xy * size - 0.5;
    vec2 f = fract(t);
    vec2 uv = (floor(t) + 0.5) / size;
    vec2 d = 1.0 / size;
    vec4 z = vec4(texture(shadow_map, uv).r, texture(shadow_map, uv + vec2(d.x, 0.0)).r,
                  texture(shadow_map, uv + vec2(0.0, d.y)).r, texture(shadow_map, uv + d).r);
    vec4 lit = step(vec4(compare), z);
    return mix(mix(lit.x, lit.y, f.x), mix(lit.z, lit.w, f.x), f.y);
}
#endif

void main()
{
    vec4 base_color = material.base_color_factor;
#ifdef HAS_BASE_COLOR_TEX
    vec4 tex = texture(material.base_color_texture, uv_0);
    base_color *= vec4(srgb_to_linear(tex.rgb), tex.a);
#endif
    float roughness = clamp(material.roughness_factor, min_roughness, 1.0);
    float metallic = clamp(material.metallic_factor, 0.0, 1.0);
    vec3 c_diff = base_color.rgb * (1.0 - min_roughness) * (1.0 - metallic);
    vec3 f0 = mix(vec3(min_roughness), base_color.rgb, metallic);
    vec3 color = base_color.rgb * ambient_light;
#ifdef NORMAL_LOC
    vec3 n = normalize(frag_normal);
#else
    vec3 n = normalize(cam_pos - frag_position);
#endif
    if (n_directional_lights > 0) {
        vec3 v = normalize(cam_pos - frag_position);
        vec3 l = -normalize(directional_lights[0].direction);
        vec3 h = normalize(l + v);
        float nl = clamp(dot(n, l), 0.001, 1.0);
        float nv = clamp(abs(dot(n, v)), 0.001, 1.0);
        float nh = clamp(dot(n, h), 0.0, 1.0);
        float vh = clamp(dot(v, h), 0.0, 1.0);
        vec3 F = f0 + (1.0 - f0) * pow(1.0 - vh, 5.0);
        float k = (roughness + 1.0) * (roughness + 1.0) / 8.0;
        float G = nv / (nv * (1.0 - k) + k) * nl / (nl * (1.0 - k) + k);
        float a2 = roughness * roughness * roughness * roughness;
        float den = nh * nh * (a2 - 1.0) + 1.0;
        float D = a2 / (PI * den * den);
        vec3 radiance = directional_lights[0].intensity * directional_lights[0].color;
        vec3 res = nl * radiance * ((1.0 - F) * c_diff / PI + F * G * D / (4.0 * nl * nv + 0.001));
#ifdef DIRECTIONAL_LIGHT_SHADOWS
        res *= lit_fraction(directional_lights[0].shadow_map, clamp(dot(n, l), 0.0, 1.0));
#endif
        color += res;
    }
    color += material.emissive_factor * material.emissive_factor;
    vec4 out_color = vec4(color, 1.0);
#ifdef COLOR_0_LOC
    out_color *= color_multiplier;
#endif
    frag_color = clamp(vec4(pow(out_color.rgb, vec3(1.0 / 2.2)), out_color.a * base_color.a), 0.0, 1.0);
}
