// sepbrdf_sample.glsl - importance sampling of non-negative factors in a shader.
//
//     bool  sb_sample(vec3 V, vec2 u, out vec3 L, out float pdf);
//     float sb_pdf(vec3 L, vec3 V);
//
// The same steps as sb_sample() / sb_pdf() of sepbrdf/sampler.h, on the
// tables of sampler.bin: V (towards the viewer) in the tangent frame, u in
// [0,1)^2; L is drawn with a density pdf (1/sr) close to f_r(L, V) cos(theta_L)
// (the factored form f cos(theta_i), or f for form f); the BRDF value is
// sb_brdf(L, V).  sb_sample returns false (L = 0, pdf = 0) when no direction
// results.  `sepbrdf factor` appends this block to sepbrdf.glsl after the
// snippet, when the factors are non-negative (--method nmf), with a header
// defining SB_SAMPLE_CH (channels of the factors), SB_HALF_ROWS (rows index
// the half vector: hd, iso), SB_COL_SAMPLE (the columns are sampled: vndf,
// vh), SB_COL_FOLD (their t axis folded, s.y in [0, 2]: vh) and the
// parameterisation's sb_row_dir() (SB_COL_SAMPLE: sb_col_dir() and
// sb_col_density()).
//
// sb_cdf: sampler.bin's float32 data as an R32F GL_TEXTURE_2D_ARRAY of
// (W + 1) x (H + 1) texels and J * SB_SAMPLE_CH + 1 layers (read with
// texelFetch only, any filter).  Layer k = j * SB_SAMPLE_CH + c: texel
// (x, y < H) the conditional CDF of texel row y, (W, y) the marginal CDF,
// (0, H) the integral of g_k; layer K = J * SB_SAMPLE_CH the solid angle of
// each cell and at (0, H) the share of cosine-weighted samples (chosen per
// material: 1 where the factored density would add noise); with
// SB_HALF_ROWS, layer K + 1 + k the weight of k for V at each cell's centre
// (read bilinear between the centres).  With SB_COL_SAMPLE, W x H are the
// cells between the h textures' nodes, (0, H) of layer k the integral of
// h_k over the unit square of s, and layer K holds the share alone.  In
// every layout layer K holds at (W, H) the share of the GGX lobe and at
// (W, 0) its roughness alpha (0: no lobe; sb_lobe_dir, sb_lobe_pdf).

uniform sampler2DArray sb_cdf;

const float SB_ONE_MINUS = 0.99999994; // the largest float below 1

float sb_cdf_at(int k, ivec2 p) { return texelFetch(sb_cdf, ivec3(p, k), 0).r; }

// Smallest i < n with u < cdf(o + i step) (binary search), u rescaled to
// [0, 1) within entry i.
int sb_cdf_find(int k, ivec2 o, ivec2 step, int n, inout float u) {
    int lo = 0, hi = n - 1;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (u < sb_cdf_at(k, o + mid * step))
            hi = mid;
        else
            lo = mid + 1;
    }
    float below = lo > 0 ? sb_cdf_at(k, o + (lo - 1) * step) : 0.0;
    u = clamp((u - below) / (sb_cdf_at(k, o + lo * step) - below), 0.0, SB_ONE_MINUS);
    return lo;
}

float sb_cdf_prob(int k, ivec2 o, ivec2 step, int i) {
    return sb_cdf_at(k, o + i * step) - (i > 0 ? sb_cdf_at(k, o + (i - 1) * step) : 0.0);
}

// SB_COL_SAMPLE: node (x, y) of h_k (texel (x, y) of the h texture, times
// the layout's sb_col_weight where it defines SB_COL_WEIGHT), and
// t in [0, 1] with density proportional to (1 - t) a + t b by u (the C's
// sample_linear, src/factor/sampler_cols.c).
float sb_node(int k, int x, int y) {
    int j = k / SB_SAMPLE_CH;
    float v = texelFetch(sb_h, ivec3(x, y, j), 0)[k - j * SB_SAMPLE_CH];
#ifdef SB_COL_WEIGHT
    // the layout's weight of the node (the snippet's sb_col_weight: vh)
    v *= sb_col_weight(vec2(float(x), float(y)) / vec2(textureSize(sb_cdf, 0).xy - 1));
#endif
    return v;
}

float sb_sample_linear(float a, float b, float u) {
    if (u == 0.0 && a == 0.0) return 0.0;
    return min(u * (a + b) / (a + sqrt(mix(a * a, b * b, u))), SB_ONE_MINUS);
}

// h_k at s in [0, 1]^2, bilinear between the nodes (the C's node_lerp).
float sb_node_lerp(int k, vec2 s) {
    ivec2 n = textureSize(sb_cdf, 0).xy - 1;
    vec2 q = clamp(s, vec2(0.0), vec2(1.0)) * vec2(n);
    ivec2 i = min(ivec2(q), n - 1);
    vec2 f = q - vec2(i);
    return (1.0 - f.y) * ((1.0 - f.x) * sb_node(k, i.x, i.y) + f.x * sb_node(k, i.x + 1, i.y)) +
           f.y * ((1.0 - f.x) * sb_node(k, i.x, i.y + 1) + f.x * sb_node(k, i.x + 1, i.y + 1));
}

// Number of distributions K = J * SB_SAMPLE_CH (layers 0 .. K - 1; layer K
// holds the cells' solid angles, layers K + 1 .. 2K the weight tables of
// the half-vector layouts).
int sb_dists() {
#if SB_HALF_ROWS
    return (textureSize(sb_cdf, 0).z - 1) / 2;
#else
    return textureSize(sb_cdf, 0).z - 1;
#endif
}

// The share of cosine-weighted samples (sampler.bin, layer K at (0, H)).
float sb_cosine_share() { return sb_cdf_at(sb_dists(), ivec2(0, textureSize(sb_cdf, 0).y - 1)); }

// The GGX lobe's share and alpha (layer K, texels (W, H) and (W, 0)).
float sb_lobe_share() { return sb_cdf_at(sb_dists(), textureSize(sb_cdf, 0).xy - 1); }
float sb_lobe_alpha() { return sb_cdf_at(sb_dists(), ivec2(textureSize(sb_cdf, 0).x - 1, 0)); }

// ---- the GGX lobe (src/factor/sampler_lobe.c): L = V reflected about a
// normal drawn from V's visible normals (Heitz 2018), alpha a about the
// normal; its density D(h) / (2 (V.z + sqrt(a^2 |V.xy|^2 + V.z^2))).
bool sb_lobe_dir(vec3 V, float a, float u0, float u1, out vec3 D) {
    D = vec3(0.0);
    if (!(V.z > 0.0)) return false;
    vec3 v = normalize(vec3(a * V.x, a * V.y, V.z)), t1v = vec3(1.0, 0.0, 0.0);
    float len2 = v.x * v.x + v.y * v.y;
    if (len2 > 0.0) t1v = vec3(-v.y, v.x, 0.0) / sqrt(len2);
    vec3 t2v = cross(v, t1v);
    float r = sqrt(u0), phi = 2.0 * SB_PI * u1, t1 = r * cos(phi), t2 = r * sin(phi), s = 0.5 * (1.0 + v.z);
    t2 = (1.0 - s) * sqrt(max(1.0 - t1 * t1, 0.0)) + s * t2;
    vec3 m = t1 * t1v + t2 * t2v + sqrt(max(1.0 - t1 * t1 - t2 * t2, 0.0)) * v;
    vec3 h = vec3(a * m.x, a * m.y, max(m.z, 0.0));
    float n = length(h);
    if (!(n > 0.0)) return false;
    h = h / n;
    D = 2.0 * dot(h, V) * h - V;
    return true;
}

float sb_lobe_pdf(vec3 L, vec3 V, float a) {
    vec3 h = L + V;
    float n2 = dot(h, h);
    if (!(V.z > 0.0) || !(h.z > 0.0) || !(n2 > 0.0) || !(dot(h, V) > 0.0)) return 0.0;
    float a2 = a * a, k = ((h.x * h.x + h.y * h.y) / a2 + h.z * h.z) / n2;
    return 1.0 / (SB_PI * a2 * k * k) / (2.0 * (V.z + sqrt(a2 * (V.x * V.x + V.y * V.y) + V.z * V.z)));
}

// The edges of the row cells (sb_row_cell, src/param/row_cell.c): float
// constants in layer K, edge i of x (1 <= i < W) at texel (i, H), edge j
// of y (1 <= j < H) at (W, j).  The cell of L is found by comparisons
// against them, on values made by single float operations in the order
// the C takes (sb_param_row_cell), so both take the same cell.
float sb_edge_x(int i) { return sb_cdf_at(sb_dists(), ivec2(i, textureSize(sb_cdf, 0).y - 1)); }
float sb_edge_y(int j) { return sb_cdf_at(sb_dists(), ivec2(textureSize(sb_cdf, 0).x - 1, j)); }

// The theta cell of s among n: the largest i with s_x^2 + s_y^2 >=
// tan^2(theta_i) s_z^2 (edge x), by a binary search.
int sb_cell_tan2(vec3 s, int n) {
    float r2 = s.x * s.x + s.y * s.y, z2 = s.z * s.z;
    int lo = 0, hi = n - 1;
    while (lo < hi) {
        int mid = (lo + hi + 1) / 2;
        if (r2 >= sb_edge_x(mid) * z2)
            lo = mid;
        else
            hi = mid - 1;
    }
    return lo;
}

// Whether the azimuth of q is at or past phi_j = 2 pi j / n (edge y: cot phi_j).
bool sb_past_phi(vec2 q, int j, int n) {
    if (2 * j == n) return q.y < 0.0 || (q.y == 0.0 && q.x < 0.0);
    float p = q.y * sb_edge_y(j);
    return 2 * j < n ? (q.y < 0.0 || q.x <= p) : (q.y < 0.0 && q.x >= p);
}

int sb_cell_phi(vec2 q, int n) {
    int lo = 0, hi = n - 1;
    while (lo < hi) {
        int mid = (lo + hi + 1) / 2;
        if (sb_past_phi(q, mid, n))
            lo = mid;
        else
            hi = mid - 1;
    }
    return lo;
}

// @ROWS: sb_glsl_sampler puts the layout's sb_row_dir (and sb_row_cell) here

// Cell i of an axis of n cells, wrapped (repeat = 1) or clamped.
int sb_wrap_cell(int i, int n, int repeat) { return repeat == 1 ? (i + n) % n : clamp(i, 0, n - 1); }

#if SB_HALF_ROWS
// The weights' key: the g coordinate of the pair (V, V), whose half
// vector is V; the weight of k is the table bilinear between cell centres
// there (src/factor/sampler.c weight_key: continuous in V, so that float
// and double pick the same weights at a cell edge).
bool sb_weight_key(vec3 V, out vec2 key) {
    vec4 st = sb_coords(V, V);
    key = clamp(st.xy, vec2(0.0), vec2(1.0));
    return sb_domain(V, V, st);
}

float sb_weight(int k, vec2 key) {
    ivec2 n = textureSize(sb_cdf, 0).xy - 1;
    vec2 u = key * vec2(n) - vec2(0.5), f = floor(u), a = u - f;
    ivec2 i = ivec2(f);
    int x0 = sb_wrap_cell(i.x, n.x, SB_WRAP_G_S), x1 = sb_wrap_cell(i.x + 1, n.x, SB_WRAP_G_S);
    int y0 = sb_wrap_cell(i.y, n.y, SB_WRAP_G_T), y1 = sb_wrap_cell(i.y + 1, n.y, SB_WRAP_G_T), l = sb_dists() + 1 + k;
    return (1.0 - a.x) * (1.0 - a.y) * sb_cdf_at(l, ivec2(x0, y0)) + a.x * (1.0 - a.y) * sb_cdf_at(l, ivec2(x1, y0)) +
           (1.0 - a.x) * a.y * sb_cdf_at(l, ivec2(x0, y1)) + a.x * a.y * sb_cdf_at(l, ivec2(x1, y1));
}
#else
// The weights' key: the h coordinate of the pair (mirror(V), V), or with
// SB_COL_SAMPLE its g coordinate (the view's alone).
bool sb_weight_key(vec3 V, out vec2 key) {
    vec3 M = vec3(-V.xy, V.z);
    vec4 st = sb_coords(M, V);
#if SB_COL_SAMPLE
    key = st.xy;
#else
    key = st.zw;
#endif
    return sb_domain(M, V, st);
}

// Texel p of the side read at the key (h; SB_COL_SAMPLE: g), channel c.
float sb_wtexel(ivec3 p, int c) { return SB_COL_SAMPLE == 1 ? texelFetch(sb_g, p, 0)[c] : texelFetch(sb_h, p, 0)[c]; }

// Weight of distribution k: lum_c h_jc(key) I_jc (SB_COL_SAMPLE: g_jc, and
// I_jc the integral of h_jc), bilinear between the texel centres in float,
// as the C reads it (a GPU's filter may weigh the texels in 8-bit steps: at
// a steep h, 1e-3 and more of the weight).
float sb_weight(int k, vec2 key) {
    int j = k / SB_SAMPLE_CH, c = k - j * SB_SAMPLE_CH;
    vec3 lum = SB_SAMPLE_CH == 1 ? vec3(1.0) : vec3(0.2126, 0.7152, 0.0722);
    ivec2 n = SB_COL_SAMPLE == 1 ? textureSize(sb_g, 0).xy : textureSize(sb_h, 0).xy;
    int ws = SB_COL_SAMPLE == 1 ? SB_WRAP_G_S : SB_WRAP_H_S, wt = SB_COL_SAMPLE == 1 ? SB_WRAP_G_T : SB_WRAP_H_T;
    vec2 u = clamp(key, vec2(0.0), vec2(1.0)) * vec2(n) - vec2(0.5), f = floor(u), a = u - f;
    ivec2 i = ivec2(f);
    int x0 = sb_wrap_cell(i.x, n.x, ws), x1 = sb_wrap_cell(i.x + 1, n.x, ws);
    int y0 = sb_wrap_cell(i.y, n.y, wt), y1 = sb_wrap_cell(i.y + 1, n.y, wt);
    float h = (1.0 - a.x) * (1.0 - a.y) * sb_wtexel(ivec3(x0, y0, j), c) + a.x * (1.0 - a.y) * sb_wtexel(ivec3(x1, y0, j), c) +
              (1.0 - a.x) * a.y * sb_wtexel(ivec3(x0, y1, j), c) + a.x * a.y * sb_wtexel(ivec3(x1, y1, j), c);
    return lum[c] * h * sb_scale[j] * sb_cdf_at(k, ivec2(0, textureSize(sb_cdf, 0).y - 1));
}
#endif

#if SB_HALF_ROWS
// ---- half rows: only the h that can reflect V above the horizon --------
// (sepbrdf/sampler.h; the maths in src/factor/sampler_half.c).  hv = (sin
// theta_V, cos theta_V, phi_V); a row's cells span the phi arc (start,
// width), a column's the z = 1 - cos(theta) bounds (lo, hi).

vec3 sb_half_view(vec3 V) {
    float r = length(V.xy);
    return vec3(r, V.z, r > 0.0 ? sb_atan2(V.y, V.x) : 0.0);
}

float sb_wrap_pi(float d) { return d - 2.0 * SB_PI * floor((d + SB_PI) / (2.0 * SB_PI)); }

vec2 sb_row_arc(int y) {
    int W = textureSize(sb_cdf, 0).x - 1;
    vec3 d = sb_row_dir(ivec2(W - 1, y), vec2(1.0, 0.0)), e = sb_row_dir(ivec2(W - 1, y), vec2(1.0, 0.5));
    float a = sb_atan2(d.y, d.x), hw = sb_atan2(e.y, e.x) - a;
    if (hw <= 0.0) hw += 2.0 * SB_PI;
    return vec2(a, 2.0 * hw);
}

// z = 1 - cos(theta) of a unit vector, accurate near the pole.
float sb_one_minus_z(vec3 d) { return dot(d.xy, d.xy) / (1.0 + d.z); }

vec2 sb_col_z(int x) {
    return vec2(sb_one_minus_z(sb_row_dir(ivec2(x, 0), vec2(0.0))),
                sb_one_minus_z(sb_row_dir(ivec2(x, 0), vec2(1.0, 0.0))));
}

// z below which h on the arc can reflect V above the horizon.
float sb_half_zcut(vec3 hv, vec2 arc) {
    float d0 = sb_wrap_pi(arc.x - hv.z), w = arc.y, cmax;
    if (w >= 2.0 * SB_PI || (d0 <= 0.0 && d0 + w >= 0.0) || d0 + w >= 2.0 * SB_PI)
        cmax = 1.0;
    else
        cmax = max(cos(d0), cos(d0 + w));
    float t = 0.25 * SB_PI + 0.5 * sb_atan2(cmax * hv.x, hv.y), s = sin(0.5 * t);
    return 2.0 * s * s;
}

// A whole-circle row's cut cell (iso): z over [lo, lo + sb_cut_dz], phi on
// the arc valid at sb_arc_z, the cut rounded away by a 64th of the cell
// (src/factor/sampler_half.c half_cut_dz).
#define SB_CUT_STEPS 64.0
float sb_cut_dz(vec2 zb, float zc) {
    float w = zb.y - zb.x;
    return zc < zb.y ? w * max(ceil(SB_CUT_STEPS * (zc - zb.x) / w), 1.0) / SB_CUT_STEPS : w;
}
float sb_arc_z(vec2 zb, float zc) { return min(zb.x, zc - (zb.y - zb.x) / SB_CUT_STEPS); }

// Row y's cut: z_cut and the count of its cells whose z_lo is below it by a
// step of the cell or more (a thinner cut part is left out: src/factor/sampler.c cuts_of).
void sb_row_cut(vec3 hv, int y, out float zc, out int xc) {
    int lo = 0, hi = textureSize(sb_cdf, 0).x - 1;
    zc = sb_half_zcut(hv, sb_row_arc(y));
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        vec2 zb = sb_col_z(mid);
        if (zb.x < zc - (zb.y - zb.x) / SB_CUT_STEPS)
            lo = mid + 1;
        else
            hi = mid;
    }
    xc = lo;
}

float sb_row_mass(int k, int y, int xc) {
    int W = textureSize(sb_cdf, 0).x - 1;
    return xc > 0 ? sb_cdf_prob(k, ivec2(W, 0), ivec2(0, 1), y) * sb_cdf_at(k, ivec2(xc - 1, y)) : 0.0;
}

float sb_kept_mass(int k, vec3 hv) {
    float m = 0.0, zc;
    int xc;
    for (int y = 0; y < textureSize(sb_cdf, 0).y - 1; y++) {
        sb_row_cut(hv, y, zc, xc);
        m += sb_row_mass(k, y, xc);
    }
    return m;
}

// Half-width of the valid phi - phi_V at z (pi: all; 0: none); the whole
// circle within SB_FULL_ARC of c = -1, where acos's slope is unbounded
// (the C's SB_HALF_FULL_ARC, src/factor/sampler_impl.h).
#define SB_FULL_ARC 1e-5
float sb_half_width(vec3 hv, float z) {
    float ct = 1.0 - z, st = sqrt(max(z * (2.0 - z), 0.0));
    float num = -(2.0 * ct * ct - 1.0) * hv.y, den = 2.0 * st * ct * hv.x;
    if (!(den > 0.0)) return num < 0.0 ? SB_PI : 0.0;
    float c = num / den;
    // acos(c) as an atan: llvmpipe's float acos is 7e-5 off (at c = 0.78)
    return c <= -1.0 + SB_FULL_ARC ? SB_PI : (c >= 1.0 ? 0.0 : sb_atan2(sqrt((1.0 - c) * (1.0 + c)), c));
}

// The part of the arc valid at z: its length, and phi uniform over it by u.
float sb_phi_valid(vec3 hv, float z, vec2 arc, float u, out float phi) {
    float hw = sb_half_width(hv, z), d0 = sb_wrap_pi(arc.x - hv.z), len = 0.0;
    phi = 0.0;
    for (int k = -1; k <= 2 && hw > 0.0; k++)
        len += max(min(d0 + arc.y, hw + 2.0 * SB_PI * float(k)) - max(d0, -hw + 2.0 * SB_PI * float(k)), 0.0);
    float t = u * len;
    for (int k = -1; k <= 2 && hw > 0.0; k++) {
        float lo = max(d0, -hw + 2.0 * SB_PI * float(k)), hi = min(d0 + arc.y, hw + 2.0 * SB_PI * float(k));
        if (hi <= lo) continue;
        phi = hv.z + lo + min(t, hi - lo);
        if (t < hi - lo) break;
        t -= hi - lo;
    }
    return len;
}

// The factored density of L: h uniform over the cell's z range below the
// cut and the part of its arc valid at the cell's lowest z.
float sb_half_pdf(vec3 L, vec3 V, ivec2 cell, vec2 sw) {
    vec3 hv = sb_half_view(V), Hh = normalize(L + V);
    float zc, ph;
    int xc;
    sb_row_cut(hv, cell.y, zc, xc);
    if (cell.x >= xc) return 0.0;
    vec2 zb = sb_col_z(cell.x);
    vec2 arc = sb_row_arc(cell.y);
    int W = textureSize(sb_cdf, 0).x - 1, K = sb_dists();
    // iso: the valid part; hd: the whole cell, its solid angle from the table
    float c = dot(Hh, V), area = sb_cdf_at(K, cell);
    if (arc.y >= 2.0 * SB_PI - 1e-3) area = sb_cut_dz(zb, zc) * sb_phi_valid(hv, sb_arc_z(zb, zc), arc, 0.0, ph);
    if (!(c > 0.0) || !(area > 0.0)) return 0.0;
    float num = 0.0, total = 0.0;
    for (int k = 0; k < K; k++) {
        float w = sb_weight(k, sw);
        if (!(w > 0.0)) continue;
        total += w;
        float m = sb_kept_mass(k, hv);
        if (m > 0.0)
            num += w * sb_cdf_prob(k, ivec2(W, 0), ivec2(0, 1), cell.y) *
                   sb_cdf_prob(k, ivec2(0, cell.y), ivec2(1, 0), cell.x) / m;
    }
    return total > 0.0 ? num / total / area / (4.0 * c) : 0.0;
}

// Distribution k's cell among those V's cuts keep (row by u0, column by
// u1, both rescaled), then h in it and D = 2 (V.h) h - V.
bool sb_half_dir(vec3 V, int k, float u0, float u1, out vec3 D) {
    D = vec3(0.0);
    vec3 hv = sb_half_view(V);
    int H = textureSize(sb_cdf, 0).y - 1, y = H, last = 0, xc;
    float total = sb_kept_mass(k, hv), target = u0 * total, acc = 0.0, m = 0.0, zc;
    if (!(total > 0.0)) return false;
    for (int r = 0; r < H; r++) {
        sb_row_cut(hv, r, zc, xc);
        float mr = sb_row_mass(k, r, xc);
        if (!(mr > 0.0)) continue;
        last = r;
        if (target < acc + mr) {
            y = r;
            m = mr;
            break;
        }
        acc += mr;
    }
    if (y == H) { // rounding ran past the end
        y = last;
        sb_row_cut(hv, y, zc, xc);
        m = sb_row_mass(k, y, xc);
        acc = total - m;
    }
    u0 = clamp((target - acc) / m, 0.0, SB_ONE_MINUS);
    sb_row_cut(hv, y, zc, xc);
    u1 *= sb_cdf_at(k, ivec2(xc - 1, y)); // the conditional up to the cut
    int x = sb_cdf_find(k, ivec2(0, y), ivec2(1, 0), xc, u1);
    vec2 zb = sb_col_z(x), arc = sb_row_arc(y);
    bool circle = arc.y >= 2.0 * SB_PI - 1e-3;
    float z = zb.x + u1 * (circle ? sb_cut_dz(zb, zc) : zb.y - zb.x), phi;
    if (!(z <= zc)) return false;
    if (!circle)
        phi = arc.x + u0 * arc.y;
    else if (!(sb_phi_valid(hv, sb_arc_z(zb, zc), arc, u0, phi) > 0.0))
        return false;
    float st = sqrt(max(z * (2.0 - z), 0.0));
    vec3 Hh = vec3(st * cos(phi), st * sin(phi), 1.0 - z);
    float c = dot(Hh, V);
    if (!(c > 0.0)) return false;
    D = 2.0 * c * Hh - V;
    return true;
}
#endif

float sb_factored_pdf(vec3 L, vec3 V, vec2 st_g, vec2 sw) {
    ivec3 n = textureSize(sb_cdf, 0);
    int W = n.x - 1, H = n.y - 1, K = sb_dists();
#ifdef SB_ROW_CELL
    ivec2 cell = sb_row_cell(L, V);
#else
    ivec2 cell = clamp(ivec2(floor(st_g * vec2(W, H))), ivec2(0), ivec2(W - 1, H - 1));
#endif
#if SB_HALF_ROWS
    return sb_half_pdf(L, V, cell, sw);
#elif SB_COL_SAMPLE
    // the density of the bilinear h_k over s, times |ds/dL| (continuous in s)
    vec2 s;
    float jac = sb_col_density(L, V, s), num = 0.0, total = 0.0;
    if (!(jac > 0.0)) return 0.0;
    for (int k = 0; k < K; k++) {
        float w = sb_weight(k, sw);
        if (!(w > 0.0)) continue;
        total += w;
        num += w / sb_cdf_at(k, ivec2(0, H)) * sb_node_lerp(k, s);
    }
    return total > 0.0 ? num / total * jac : 0.0;
#else
    float num = 0.0, total = 0.0;
    for (int k = 0; k < K; k++) {
        float w = sb_weight(k, sw);
        if (!(w > 0.0)) continue;
        total += w;
        num += w * sb_cdf_prob(k, ivec2(W, 0), ivec2(0, 1), cell.y) *
               sb_cdf_prob(k, ivec2(0, cell.y), ivec2(1, 0), cell.x);
    }
    return total > 0.0 ? num / total / sb_cdf_at(K, cell) : 0.0;
#endif
}

float sb_pdf(vec3 L, vec3 V) {
    vec4 st = sb_coords(L, V);
    vec2 sw;
    if (!sb_domain(L, V, st) || !sb_weight_key(V, sw)) return 0.0;
    float s = sb_cosine_share(), sl = sb_lobe_share(), rest = 1.0 - s - sl;
    float lobe = sl > 0.0 ? sl * sb_lobe_pdf(L, V, sb_lobe_alpha()) : 0.0;
    return s * L.z / SB_PI + lobe + (rest > 0.0 ? rest * sb_factored_pdf(L, V, st.xy, sw) : 0.0);
}

// The factored component: distribution k by u0, then the cell's row y (u0
// rescaled) and column x (u1), a direction in the cell, reflected for half rows.
bool sb_factored_dir(vec3 V, vec2 sw, float u0, float u1, out vec3 D) {
    D = vec3(0.0);
    ivec3 n = textureSize(sb_cdf, 0);
    int W = n.x - 1, H = n.y - 1, K = sb_dists();
    float total = 0.0;
    for (int k = 0; k < K; k++)
        total += sb_weight(k, sw);
    if (!(total > 0.0)) return false;
    float target = u0 * total, acc = 0.0;
    int pick = -1, last = 0;
    for (int k = 0; k < K && pick < 0; k++) {
        float w = sb_weight(k, sw);
        if (!(w > 0.0)) continue;
        if (target < acc + w) {
            pick = k;
            u0 = clamp((target - acc) / w, 0.0, SB_ONE_MINUS);
        }
        last = k;
        acc += w;
    }
    if (pick < 0) {
        pick = last;
        u0 = SB_ONE_MINUS;
    }
#if SB_HALF_ROWS
    return sb_half_dir(V, pick, u0, u1, D);
#elif SB_COL_SAMPLE
    // either half of a folded t axis by the term's remainder (SB_COL_FOLD: vh's phi)
    bool mirror = false;
#if SB_COL_FOLD
    if (u0 >= 0.5) {
        mirror = true;
        u0 = 2.0 * u0 - 1.0;
    } else {
        u0 = 2.0 * u0;
    }
#endif
    // the cell between the nodes, then s in it by the bilinear patch
    int y = sb_cdf_find(pick, ivec2(W, 0), ivec2(0, 1), H, u0);
    int x = sb_cdf_find(pick, ivec2(0, y), ivec2(1, 0), W, u1);
    float v0 = sb_node(pick, x, y), v1 = sb_node(pick, x + 1, y);
    float v2 = sb_node(pick, x, y + 1), v3 = sb_node(pick, x + 1, y + 1);
    float fy = sb_sample_linear(v0 + v1, v2 + v3, u0);
    float fx = sb_sample_linear(v0 + fy * (v2 - v0), v1 + fy * (v3 - v1), u1);
    vec2 s = (vec2(float(x), float(y)) + vec2(fx, fy)) / vec2(float(W), float(H));
    return sb_col_dir(V, mirror ? vec2(s.x, 2.0 - s.y) : s, D);
#else
    int y = sb_cdf_find(pick, ivec2(W, 0), ivec2(0, 1), H, u0);
    int x = sb_cdf_find(pick, ivec2(0, y), ivec2(1, 0), W, u1);
    D = sb_row_dir(ivec2(x, y), vec2(u1, u0));
    return true;
#endif
}

bool sb_sample(vec3 V, vec2 u, out vec3 L, out float pdf) {
    L = vec3(0.0);
    pdf = 0.0;
    vec2 sw;
    if (!sb_weight_key(V, sw)) return false;
    vec3 D;
    float s = sb_cosine_share(), sl = sb_lobe_share();
    if (u.x < s) { // cosine-weighted share
        float r = sqrt(u.x / s), phi = 2.0 * SB_PI * u.y;
        D = vec3(r * cos(phi), r * sin(phi), sqrt(max(1.0 - r * r, 0.0)));
    } else if (u.x < s + sl) { // the GGX lobe
        if (!sb_lobe_dir(V, sb_lobe_alpha(), min((u.x - s) / sl, SB_ONE_MINUS), u.y, D)) return false;
    } else if (!sb_factored_dir(V, sw, min((u.x - s - sl) / (1.0 - s - sl), SB_ONE_MINUS), u.y, D)) {
        return false;
    }
    vec3 Ln = normalize(D);
    float p = sb_pdf(Ln, V);
    if (!(p > 0.0) || !(Ln.z > 0.0)) return false;
    L = Ln;
    pdf = p;
    return true;
}
