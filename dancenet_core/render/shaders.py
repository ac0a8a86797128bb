"""The preview's GLSL: one vertex shader, and one fragment shader compiled three ways (FIGURE, FLOOR, SHADOW)."""

# pyrender's metallic-roughness shading (its shaders/mesh.frag), written out for what the preview draws: dielectrics
# (metallic 0, f0 0.04) under white directional lights plus ambient light. Hand-written for speed: pyrender's
# general shader loops over absent kinds of light and texture in every pixel. Its terms that do not depend on the
# colour are scalars here (colour = base * diffuse + specular); gamma 2.2 out, as pyrender's.
_VERTEX_SHADER = """
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 normal;
layout(location = 2) in vec4 colour;
layout(location = 3) in vec2 uv;
uniform mat4 view_projection;
out vec3 frag_position;
out vec3 frag_normal;
out vec4 frag_colour;
out vec2 frag_uv;
void main() {
    gl_Position = view_projection * vec4(position, 1.0);
    frag_position = position;
    frag_normal = normalize(normal);
    frag_colour = colour;
    frag_uv = uv;
}
"""

_FRAGMENT_SHADER = """
in vec3 frag_position;
in vec3 frag_normal;
in vec4 frag_colour;
in vec2 frag_uv;
uniform vec3 cam_pos;
uniform vec3 to_light[N_LIGHTS];
uniform float intensity[N_LIGHTS];
uniform vec3 ambient;
uniform float roughness;
uniform sampler2D tex;
out vec4 out_colour;
const float PI = 3.141592653589793;

vec2 diffuse_specular(vec3 n) {
    vec3 v = normalize(cam_pos - frag_position);
    float nv = clamp(abs(dot(n, v)), 0.001, 1.0);
    float r = roughness + 1.0;
    float k = r * r / 8.0;
    float g1 = nv / (nv * (1.0 - k) + k);
    float a = roughness * roughness;
    float a2 = a * a;
    vec2 sum = vec2(0.0);
    for (int i = 0; i < N_LIGHTS; i++) {
        vec3 l = to_light[i];
        vec3 h = normalize(l + v);
        float nl = clamp(dot(n, l), 0.001, 1.0);
        float nh = clamp(dot(n, h), 0.0, 1.0);
        float vh = clamp(dot(v, h), 0.0, 1.0);
        float c = clamp(1.0 - vh, 0.0, 1.0);
        float f = 0.04 + 0.96 * (c * c) * (c * c) * c;
        float g = g1 * nl / (nl * (1.0 - k) + k);
        float d = nh * nh * (a2 - 1.0) + 1.0;
        d = a2 / (PI * d * d);
        sum += nl * intensity[i] * vec2((1.0 - f) * 0.96 / PI, f * g * d / (4.0 * nl * nv + 0.001));
    }
    return sum;
}

void main() {
#if defined(SHADOW)
    out_colour = vec4(0.0, 0.0, 0.0, frag_colour.a * texture(tex, frag_uv).r);
#else
#if defined(FLOOR)  // the grid's sRGB grey, made linear, on a floor facing up
    float s = texture(tex, frag_uv).r;
    vec3 base = vec3(s < 0.04045 ? s / 12.92 : pow((s + 0.055) / 1.055, 2.4));
    vec4 multiplier = vec4(1.0);
    vec2 ds = diffuse_specular(vec3(0.0, 1.0, 0.0));
#else  // white, times the vertex colour after lighting
    vec3 base = vec3(1.0);
    vec4 multiplier = frag_colour;
    vec2 ds = diffuse_specular(normalize(frag_normal));
#endif
    vec3 colour = (base * ds.x + ds.y + base * ambient) * multiplier.rgb;
    out_colour = clamp(vec4(pow(colour, vec3(1.0 / 2.2)), multiplier.a), 0.0, 1.0);
#endif
}
"""
