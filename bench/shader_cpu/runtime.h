// The CPU runtime of bench/shader_cpu.py: the emitted HLSL, Metal and WGSL
// snippets compiled as C++ (clang++) over tests/data/metal/metal_stdlib's
// vector types, with the texture reads written here from the APIs' own
// rules (GL_LINEAR / filter::linear / MIN_MAG_MIP_LINEAR at lod 0, texel x
// centred at (x + 0.5) / W, clamp-to-edge or repeat per axis; loads exact).
// No sepbrdf code: what a GPU would do with the snippet as written.
#pragma once
#include <metal_stdlib>

#include <cstdio>
#include <cstdlib>
#include <map>

namespace metal {
// clang-format off
SB_EW1(round, std::round)
SB_EW1(exp, std::exp) SB_EW1(log, std::log) SB_EW1(tan, std::tan) SB_EW1(asin, std::asin) SB_EW1(ceil, std::ceil)
    SB_EW1(trunc, std::trunc) SB_EW1(saturate, [](float x) {
        return x < 0 ? 0.0f : x > 1 ? 1.0f : x;
    }) SB_EW1(sign, [](float x) {
        return x > 0 ? 1.0f : x < 0 ? -1.0f : 0.0f;
    }) SB_EW2(pow, std::pow(a, b)) SB_EW2(step, b < a ? 0 : 1) // clang-format on
    inline float fmod(float a, float b) {
    return std::fmod(a, b);
}
} // namespace metal

struct sb_tex { /* one texture (array): layers x h x w x 4 floats */
    int w, h, layers, wrap_s, wrap_t;
    const float *d;
};
static std::map<const void *, sb_tex> sb_texs;

static float sb_texel(const sb_tex &t, int l, int y, int x, int c) {
    return t.d[(((size_t)l * t.h + y) * t.w + x) * 4 + c];
}
static int sb_wrap(int i, int n, int rep) { return rep ? ((i % n) + n) % n : (i < 0 ? 0 : i >= n ? n - 1 : i); }
static float4 sb_linear(const void *self, float2 st, int layer) {
    const sb_tex &t = sb_texs.at(self);
    if (layer < 0) layer = 0;
    if (layer >= t.layers) layer = t.layers - 1;
    float u = st.x * t.w - 0.5f, v = st.y * t.h - 0.5f;
    int x0 = (int)std::floor(u), y0 = (int)std::floor(v);
    float a = u - x0, b = v - y0;
    float4 r;
    for (int c = 0; c < 4; c++) {
        int xa = sb_wrap(x0, t.w, t.wrap_s), xb = sb_wrap(x0 + 1, t.w, t.wrap_s);
        int ya = sb_wrap(y0, t.h, t.wrap_t), yb = sb_wrap(y0 + 1, t.h, t.wrap_t);
        r[c] = (1 - a) * (1 - b) * sb_texel(t, layer, ya, xa, c) + a * (1 - b) * sb_texel(t, layer, ya, xb, c) +
               (1 - a) * b * sb_texel(t, layer, yb, xa, c) + a * b * sb_texel(t, layer, yb, xb, c);
    }
    return r;
}
static float4 sb_load(const void *self, int x, int y, int layer) {
    const sb_tex &t = sb_texs.at(self);
    float4 r;
    for (int c = 0; c < 4; c++)
        r[c] =
            x >= 0 && y >= 0 && x < t.w && y < t.h && layer >= 0 && layer < t.layers ? sb_texel(t, layer, y, x, c) : 0;
    return r;
}

/* Metal */
template <> float4 metal::texture2d_array<float>::sample(metal::sampler, float2 st, uint layer) const {
    return sb_linear(this, st, (int)layer);
}
template <> float4 metal::texture2d_array<float>::read(uint2 p, uint layer, uint) const {
    return sb_load(this, (int)p.x, (int)p.y, (int)layer);
}
template <> uint metal::texture2d_array<float>::get_width(uint) const { return sb_texs.at(this).w; }
template <> uint metal::texture2d_array<float>::get_height(uint) const { return sb_texs.at(this).h; }
template <> uint metal::texture2d_array<float>::get_array_size() const { return sb_texs.at(this).layers; }
template <> float4 metal::texture2d<float>::read(uint2 p, uint) const { return sb_load(this, (int)p.x, (int)p.y, 0); }

/* HLSL */
struct SamplerState {};
template <class T> struct Texture2DArray {
    float4 SampleLevel(SamplerState, float3 c, float) const { return sb_linear(this, c.xy, (int)std::round(c.z)); }
    float4 Load(int4 p) const { return sb_load(this, p.x, p.y, p.z); }
    void GetDimensions(uint &w, uint &h, uint &n) const {
        w = sb_texs.at(this).w, h = sb_texs.at(this).h, n = sb_texs.at(this).layers;
    }
    void GetDimensions(uint lod, uint &w, uint &h, uint &n, uint &levels) const {
        (void)lod;
        GetDimensions(w, h, n);
        levels = 1;
    }
};
template <class T> struct Texture2D {
    float4 Load(int3 p) const { return sb_load(this, p.x, p.y, 0); }
};
#define lerp mix
#define frac fract

/* WGSL */
struct sb_wtex2a {};
struct sb_wtex2 {};
typedef metal::sampler sampler_w;
inline float4 textureSampleLevel(const sb_wtex2a &t, metal::sampler, float2 st, int layer, float) {
    return sb_linear(&t, st, layer);
}
inline float4 textureLoad(const sb_wtex2a &t, int2 p, int layer, int) { return sb_load(&t, p.x, p.y, layer); }
inline float4 textureLoad(const sb_wtex2 &t, int2 p, int) { return sb_load(&t, p.x, p.y, 0); }
inline uint2 textureDimensions(const sb_wtex2a &t, int = 0) {
    uint2 r;
    r.x = sb_texs.at(&t).w, r.y = sb_texs.at(&t).h;
    return r;
}
inline uint textureNumLayers(const sb_wtex2a &t) { return sb_texs.at(&t).layers; }
template <class T> T select(T f, T t, bool c) { return c ? t : f; }
