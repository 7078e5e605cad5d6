// sepbrdf.glsl - evaluate a separable BRDF approximation in a shader.
//
//     f_r(L, V) ~ sum_{j < SB_TERMS} g_j(L) * h_j(V)      (per RGB channel)
//
// L (towards the light) and V (towards the viewer) are unit vectors in the
// tangent frame (z = normal, x = tangent).  The g_j are the layers of the
// texture array sb_g, the h_j those of sb_h, uploaded from the EXR files
// g_JJ.exr / h_JJ.exr that `sepbrdf factor` writes (layer j = file JJ).
// Sampler state: GL_LINEAR min/mag filter, no mipmaps; wrap per axis as the
// parameterisation says (SB_WRAP_G_S ... below: 0 = CLAMP_TO_EDGE,
// 1 = REPEAT).  Texel x of a W-wide texture has its centre at s = (x+0.5)/W,
// the OpenGL convention, which the CPU reconstruction follows exactly;
// with SB_EDGE_H_S 1 the h lookup continues the line through the last two
// texel centres along s beyond the last one (sb_texture_h).
//
// `sepbrdf factor` writes this file into its output folder with a header of
// #defines for that factorisation (SB_TERMS, SB_FORM, SB_THETA_MAX, the
// per-term scales of half-float output) and the parameterisation's
// sb_coords()/sb_domain() functions.  Include it after your #version line.

uniform sampler2DArray sb_g;
uniform sampler2DArray sb_h;

// h_j at st: texture(), but with SB_EDGE_H_S beyond the last texel centre
// along s (x > n - 1 in texels, at most half a texel: iso's theta_d towards
// the horizon) the line through the last two texel centres instead of the
// edge texel's value, as the C reconstruction (sb_factors_eval) does.
vec3 sb_texture_h(vec2 st, int j) {
#if SB_EDGE_H_S
    float n = float(textureSize(sb_h, 0).x);
    float e = min(st.x * n - 0.5, n - 0.5) - (n - 1.0);
    if (e > 0.0 && n > 1.5) {
        vec3 last = texture(sb_h, vec3((n - 0.5) / n, st.y, float(j))).rgb;
        vec3 before = texture(sb_h, vec3((n - 1.5) / n, st.y, float(j))).rgb;
        return last + (last - before) * e;
    }
#endif
    return texture(sb_h, vec3(st, float(j))).rgb;
}

vec3 sb_brdf(vec3 L, vec3 V) {
    vec4 st = sb_coords(L, V);
    if (!sb_domain(L, V, st)) return vec3(0.0);
    vec3 sum = vec3(0.0);
    for (int j = 0; j < SB_TERMS; j++) {
        vec3 g = texture(sb_g, vec3(st.xy, float(j))).rgb;
        vec3 h = sb_texture_h(st.zw, j);
        sum += g * h * sb_scale[j];
    }
#ifdef SB_GAIN
    sum = max(sum, vec3(0.0)) * sb_gain(L, V);  // the layout's known factor (vndf: the RGL file's NDF / 4 sigma)
#elif SB_CLAMP
    sum = max(sum, vec3(0.0));  // no negative value (SB_CLAMP 0: the plain truncated SVD's sum)
#endif
#if SB_FORM == 1
    sum /= max(L.z, 0.001);            // factored f cos(theta_i)
#elif SB_FORM == 2
    sum /= max(L.z, 0.001) * max(V.z, 0.001);  // factored f cos(theta_i) cos(theta_o)
#endif
    return sum;
}
