/* CLI: `sepbrdf info FILE.exr` on factor files written by the real binary
 * (SB_CLI), and on files that are not factor files. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"

static char out[65536];

static int run(const char *fmt, const char *a) {
    char cmd[8192], tail[6000];
    snprintf(tail, sizeof tail, fmt, a);
    snprintf(cmd, sizeof cmd, "%s %s", SB_CLI, tail);
    return sb_run(cmd, out, sizeof out);
}

static const char *factor_dir(void) {
    static char dir[4200];
    snprintf(dir, sizeof dir, "%s", sb_tmpdir("info"));
    int rc = run("factor microfacet:base=copper,roughness=0.6 --param io --res 8 -J 3 -q -o %s", dir);
    CHECKF(rc == 0, "factor: rc %d: %s", rc, out);
    return dir;
}

SB_TEST(factor_file) {
    const char *dir = factor_dir();
    char path[4300];
    snprintf(path, sizeof path, "%s/h_01.exr", dir);
    int rc = run("info %s", path);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    const char *want[] = {"h_01", "term 1 of J = 3", "8 x 8 texels", "R = 8",   "io:res=8", "microfacet:base=",
                          "form", "method",          "sigma_j",      "rel_rms", "float32"};
    for (size_t i = 0; i < sizeof want / sizeof want[0]; i++)
        CHECKF(strstr(out, want[i]), "lacks %s: %s", want[i], out);
    CHECKF(!strstr(out, " ?"), "a sigma is missing: %s", out);
    /* sigma_0 of R as in report.json */
    char rep[4300];
    snprintf(rep, sizeof rep, "%s/report.json", dir);
    FILE *fp = fopen(rep, "r");
    CHECK(fp != NULL);
    if (!fp) return;
    static char buf[1 << 16];
    size_t n = fread(buf, 1, sizeof buf - 1, fp);
    buf[n] = 0;
    fclose(fp);
    const char *s = strstr(buf, "\"sigma\": {\n    \"R\": [\n      ");
    CHECK(s != NULL);
    if (!s) return;
    double sigma0 = atof(s + strlen("\"sigma\": {\n    \"R\": [\n      "));
    const char *row = strstr(out, "sigma_j");
    row = row ? strstr(row, "\n") : NULL; /* the j = 0 line */
    CHECK(row != NULL);
    if (!row) return;
    double j0, r0;
    CHECK(sscanf(row, " %lf %lf", &j0, &r0) == 2);
    CHECK(j0 == 0);
    CHECK_REL(r0, sigma0, 1e-5); /* printed with 6 digits from a float */
}

SB_TEST(missing_sibling) {
    const char *dir = factor_dir();
    char path[4300];
    snprintf(path, sizeof path, "%s/g_01.exr", dir);
    CHECK(remove(path) == 0);
    snprintf(path, sizeof path, "%s/g_00.exr", dir);
    int rc = run("info %s", path);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    CHECKF(strstr(out, " ?"), "the missing term's sigma is not marked: %s", out);
}

SB_TEST(not_factor_files) {
    const char *dir = factor_dir();
    char path[4300], cmd[20000];
    snprintf(path, sizeof path, "%s/report.json", dir);
    CHECK(run("info %s", path) == 2);
    CHECKF(strstr(out, "report.json") != NULL, "message does not name the file: %s", out);
    /* a text file named .exr, and a truncated EXR */
    snprintf(cmd, sizeof cmd, "cp %s/report.json %s/fake.exr && head -c 200 %s/g_00.exr > %s/cut.exr", dir, dir, dir,
             dir);
    CHECK(sb_run(cmd, NULL, 0) == 0);
    snprintf(path, sizeof path, "%s/fake.exr", dir);
    CHECK(run("info %s", path) == 2);
    CHECK(strstr(out, "fake.exr"));
    snprintf(path, sizeof path, "%s/cut.exr", dir);
    CHECK(run("info %s", path) == 2);
    CHECK(strstr(out, "cut.exr"));
    snprintf(path, sizeof path, "%s/missing.exr", dir);
    CHECK(run("info %s", path) == 2);
    CHECK(strstr(out, "missing.exr"));
    /* cut after its header, within its last chunk: described as whole, exit 0, before */
    snprintf(cmd, sizeof cmd, "head -c $(( $(stat -c %%s %s/g_00.exr) - 9 )) %s/g_00.exr > %s/short.exr", dir, dir,
             dir);
    CHECK(sb_run(cmd, NULL, 0) == 0);
    snprintf(path, sizeof path, "%s/short.exr", dir);
    int rc = run("info %s 2>&1", path);
    CHECKF(rc == 2 && strstr(out, "short.exr") && strstr(out, "cut short"), "rc %d: %s", rc, out);
}

/* info on folders: the set `factor` wrote is described by its first
 * texture and its report named (before: "not a file this command
 * knows"); a folder without factors (a render's) is refused saying what
 * info takes; view on a render's folder says that it is one (before:
 * "g_00.exr: cannot read as OpenEXR"). */
SB_TEST(folders) {
    const char *dir = factor_dir();
    int rc = run("info %s", dir);
    CHECKF(rc == 0 && strstr(out, "a factor set") && strstr(out, "report.json") && strstr(out, "term 0 of J = 3"),
           "rc %d: %s", rc, out);
    char rdir[4300];
    snprintf(rdir, sizeof rdir, "%s/r", sb_tmpdir("info_render"));
    rc = run("render lambert -s 16 -o %s", rdir);
    CHECKF(rc == 0, "render: rc %d: %s", rc, out);
    rc = run("info %s", rdir);
    CHECKF(rc == 2 && strstr(out, "a folder without factors") && strstr(out, "a folder `factor` wrote"), "rc %d: %s",
           rc, out);
    rc = run("view %s", rdir);
    CHECKF(rc == 2 && strstr(out, "no factors in it") && strstr(out, "`sepbrdf render` wrote"), "rc %d: %s", rc, out);
}

/* `info --json` on a factor texture and on a factor folder prints one JSON
 * object (it printed the text table, exit 0, under --json). */
SB_TEST(json_for_factor_files) {
    const char *dir = factor_dir();
    char g[4300];
    snprintf(g, sizeof g, "%s/h_01.exr", dir);
    const char *args[2] = {g, dir};
    const char *kinds[2] = {"\"kind\": \"factor texture\"", "\"kind\": \"factor set\""};
    for (int k = 0; k < 2; k++) {
        int rc = run("info %s --json 2>/dev/null", args[k]);
        size_t n = strlen(out);
        while (n && (out[n - 1] == '\n' || out[n - 1] == ' '))
            n--;
        CHECKF(rc == 0 && out[0] == '{' && n && out[n - 1] == '}', "rc %d: %s", rc, out);
        CHECKF(strstr(out, kinds[k]) && strstr(out, "\"terms\": 3") && strstr(out, "\"rel_rms\": [") &&
                   !strstr(out, "sepbrdf factor texture ("),
               "%s", out);
    }
    CHECK(strstr(out, "\"report\": \"") && strstr(out, "\"texture\": {") && strstr(out, "g_00.exr"));
}

/* The (width, height) of an EXR's dataWindow, read from its header bytes
 * (an independent reading: no OpenEXR); 0 when not found. */
static int exr_size(const char *path, long *w, long *h) {
    FILE *fp = fopen(path, "rb");
    static unsigned char buf[4096];
    size_t n = fp ? fread(buf, 1, sizeof buf, fp) : 0;
    if (fp) fclose(fp);
    static const char key[] = "dataWindow\0box2i";
    for (size_t i = 0; i + sizeof key + 20 <= n; i++) {
        if (memcmp(buf + i, key, sizeof key) != 0) continue;
        const unsigned char *b = buf + i + sizeof key + 4; /* past the size */
        int32_t v[4];
        for (int k = 0; k < 4; k++)
            v[k] = (int32_t)((uint32_t)b[4 * k] | (uint32_t)b[4 * k + 1] << 8 | (uint32_t)b[4 * k + 2] << 16 |
                             (uint32_t)b[4 * k + 3] << 24);
        *w = v[2] - v[0] + 1;
        *h = v[3] - v[1] + 1;
        return 1;
    }
    return 0;
}

/* info on the vndf.exr `factor` writes beside an RGL file's vndf fit: its
 * size and channels, exit 0 (it said "not a factor file", exit 2, on a file
 * factor itself wrote); the same tables under another name too, by their
 * sepbrdf.kind (they were refused).  factor's last line names the file. */
SB_TEST(vndf_tables) {
    const char *dir = sb_tmpdir("info_vndf");
    int rc = run("factor " SB_MEASURED_DIR "/rgl_chm_orange_rgb.bsdf --param vndf -J 1 -o %s", dir);
    CHECKF(rc == 0, "factor: rc %d: %s", rc, out);
    /* its last line names vndf.exr, in the singular (was "1 texture pairs" and "1 terms") */
    CHECKF(strstr(out, "wrote 1 texture pair, vndf.exr, report.json and sepbrdf.glsl") && strstr(out, " 1 term, "),
           "%s", out);
    char path[4300], want[128], cmd[9000];
    snprintf(path, sizeof path, "%s/vndf.exr", dir);
    long w = 0, h = 0;
    CHECK(exr_size(path, &w, &h) && w > 1 && h > 1);
    rc = run("info %s", path);
    snprintf(want, sizeof want, "size       %ld x %ld texels", w, h);
    CHECKF(rc == 0 && strstr(out, "vndf tables") && strstr(out, want) && strstr(out, "channels   3:"), "rc %d: %s", rc,
           out);
    rc = run("info %s --json 2>/dev/null", path);
    snprintf(want, sizeof want, "\"width\": %ld", w);
    CHECKF(rc == 0 && out[0] == '{' && strstr(out, "\"kind\": \"vndf tables\"") && strstr(out, want), "rc %d: %s", rc,
           out);
    snprintf(cmd, sizeof cmd, "cp %s %s/tables.exr", path, dir);
    CHECK(sb_run(cmd, NULL, 0) == 0);
    snprintf(path, sizeof path, "%s/tables.exr", dir);
    rc = run("info %s", path);
    CHECKF(rc == 0 && strstr(out, "vndf tables") && strstr(out, "channels   3:"), "rc %d: %s", rc, out);
    /* under a name without .exr, by its content (OpenEXR's magic): it said
     * "unrecognised measured table (unknown content)", exit 2 */
    static const char *const names[] = {"vndf.bin", "vndf"};
    for (size_t k = 0; k < 2; k++) {
        snprintf(cmd, sizeof cmd, "cp %s/vndf.exr %s/%s", dir, dir, names[k]);
        CHECK(sb_run(cmd, NULL, 0) == 0);
        snprintf(path, sizeof path, "%s/%s", dir, names[k]);
        rc = run("info %s 2>&1", path);
        CHECKF(rc == 0 && strstr(out, "vndf tables") && strstr(out, "channels   3:"), "%s: rc %d: %s", names[k], rc,
               out);
    }
}

/* A measured table named .exr is described as the table it is, as factor
 * reads it (content first; it said "cannot read as an EXR file", exit 2);
 * a text file named .exr keeps the EXR reader's message (not_factor_files). */
SB_TEST(measured_table_named_exr) {
    const char *dir = sb_tmpdir("info_table_exr");
    char cmd[9000], path[4300];
    snprintf(path, sizeof path, "%s/table.exr", dir);
    snprintf(cmd, sizeof cmd, "cp " SB_MEASURED_DIR "/rgl_chm_orange_rgb.bsdf %s", path);
    CHECK(sb_run(cmd, NULL, 0) == 0);
    int rc = run("info %s 2>&1", path);
    CHECKF(rc == 0 && strstr(out, "format        rgl") && strstr(out, "Orange"), "rc %d: %s", rc, out);
    snprintf(cmd, sizeof cmd, "cp " SB_MEASURED_DIR "/cornell_acryl_blue.brdf %s", path);
    CHECK(sb_run(cmd, NULL, 0) == 0);
    rc = run("info %s 2>&1", path);
    CHECKF(rc == 0 && strstr(out, "format        cornell"), "rc %d: %s", rc, out);
}

/* Where the value of header attribute `name` starts in the EXR at path,
 * or with name NULL the first entry of the offset table after the header
 * (own walk of the attributes); 0 when not found in the first 64 KiB. */
static long header_at(const char *path, const char *name) {
    FILE *fp = fopen(path, "rb");
    unsigned char buf[65536];
    size_t n = fp ? fread(buf, 1, sizeof buf, fp) : 0, pos = 8;
    if (fp) fclose(fp);
    while (pos < n && buf[pos] != 0) {
        size_t len = strnlen((const char *)buf + pos, n - pos), type = 0;
        if (pos + len + 1 < n) type = strnlen((const char *)buf + pos + len + 1, n - pos - len - 1);
        size_t at = pos + len + 1 + type + 1;
        if (at + 4 > n) return 0;
        if (name && strcmp((const char *)buf + pos, name) == 0) return (long)at + 4;
        int32_t size = (int32_t)(buf[at] | buf[at + 1] << 8 | buf[at + 2] << 16 | (uint32_t)buf[at + 3] << 24);
        pos = at + 4 + (size_t)size;
    }
    return !name && pos < n ? (long)pos + 1 : 0;
}
static long first_offset_at(const char *path) { return header_at(path, NULL); }

/* An offset table entry that points nowhere (0, or into the table): the
 * textures' reader refuses the file ("Corrupt chunk offset table"), and
 * info refuses it too, naming the scanline (twelfth outside pass: info let
 * OpenEXR rebuild the table by scanning the file and described it as
 * whole, exit 0, where render and view refused it). */
SB_TEST(corrupt_offset_table) {
    const char *dir = factor_dir();
    char path[4300], cmd[20000];
    snprintf(path, sizeof path, "%s/h_01.exr", dir);
    long at = first_offset_at(path);
    CHECK(at > 8);
    static const char *const entries[2] = {"\\000\\000\\000\\000\\000\\000\\000\\000",
                                           "\\010\\000\\000\\000\\000\\000\\000\\000"};
    for (int k = 0; k < 2 && at > 8; k++) {
        snprintf(cmd, sizeof cmd,
                 "cp %s %s/bad.exr && printf '%s' | dd of=%s/bad.exr bs=1 seek=%ld conv=notrunc status=none", path, dir,
                 entries[k], dir, at);
        CHECK(sb_run(cmd, NULL, 0) == 0);
        snprintf(path, sizeof path, "%s/bad.exr", dir);
        int rc = run("info %s 2>&1", path);
        CHECKF(rc == 2 && strstr(out, "bad.exr") && strstr(out, "scanline 0"), "entry %d: rc %d: %s", k, rc, out);
        snprintf(path, sizeof path, "%s/h_01.exr", dir);
    }
}

/* A compression byte OpenEXR does not know (200) or a method its C library
 * cannot decode (9, DWAB): OpenEXR reads the header as another method's
 * and fails only on the pixels, so render refused the file while info
 * described it ("ZIP compression", exit 0; twelfth outside pass).  info
 * now decodes the pixels as the textures' reader does: exit 2, the file
 * and the decoder's reason named. */
SB_TEST(undecodable_pixels) {
    const char *dir = factor_dir();
    char path[4300], bad[4300], cmd[20000];
    snprintf(path, sizeof path, "%s/h_01.exr", dir);
    snprintf(bad, sizeof bad, "%s/bad.exr", dir);
    long at = header_at(path, "compression");
    CHECK(at > 8);
    static const char *const bytes[2] = {"\\310", "\\011"};
    for (int k = 0; k < 2 && at > 8; k++) {
        snprintf(cmd, sizeof cmd, "cp %s %s && printf '%s' | dd of=%s bs=1 seek=%ld conv=notrunc status=none", path,
                 bad, bytes[k], bad, at);
        CHECK(sb_run(cmd, NULL, 0) == 0);
        int rc = run("info %s 2>&1", bad);
        CHECKF(rc == 2 && strstr(out, "bad.exr") && strstr(out, "decode"), "byte %s: rc %d: %s", bytes[k], rc, out);
    }
    int rc = run("info %s", path); /* the file itself reads */
    CHECKF(rc == 0 && strstr(out, "none compression"), "rc %d: %s", rc, out);
}

/* Float v into texel (x, y) of layer k of sampler tables `path`, written
 * to `bad` (a copy); 0 or -1. */
static int patch_texel(const char *path, const char *bad, uint32_t k, uint32_t x, uint32_t y, float v) {
    FILE *fp = fopen(path, "rb");
    uint32_t head[4] = {0};
    int ok = fp && fseek(fp, 8, SEEK_SET) == 0 && fread(head, 4, 4, fp) == 4; /* little-endian host */
    if (fp) fclose(fp);
    char cmd[9000];
    snprintf(cmd, sizeof cmd, "cp %s %s", path, bad);
    if (!ok || sb_run(cmd, NULL, 0) != 0 || !(fp = fopen(bad, "r+b"))) return -1;
    long at = 24 + 4 * (long)(((uint64_t)k * head[1] + y) * head[0] + x);
    ok = fseek(fp, at, SEEK_SET) == 0 && fwrite(&v, 4, 1, fp) == 1;
    return fclose(fp) == 0 && ok ? 0 : -1;
}

/* Texel (x, y) of layer k of a sampler.bin (NAN where unreadable). */
static float texel_of(const char *path, uint32_t k, uint32_t x, uint32_t y) {
    FILE *fp = fopen(path, "rb");
    uint32_t head[4] = {0};
    float v = NAN;
    if (fp && fseek(fp, 8, SEEK_SET) == 0 && fread(head, 4, 4, fp) == 4 &&
        fseek(fp, 24 + 4 * (long)(((uint64_t)k * head[1] + y) * head[0] + x), SEEK_SET) == 0 &&
        fread(&v, 4, 1, fp) != 1)
        v = NAN;
    if (fp) fclose(fp);
    return v;
}

/* The sampler's tables (sampler.bin) described: sizes, layers and the
 * cosine and GGX lobe shares, as the GLSL sampler reads them; a damaged
 * copy refused (exit 2) naming the layer, texel and value.  info said
 * "unrecognised measured table" of every sampler.bin (thirteenth outside
 * pass), whole or damaged; a row cell measure of 0 or below and a texel
 * written 0 that the GLSL does not read, changed, were described as whole
 * (fourteenth pass). */
SB_TEST(sampler_tables) {
    const char *dir = sb_tmpdir("info_sampler");
    int rc =
        run("factor " SB_MEASURED_DIR "/rgl_paper_white_rgb.bsdf --method nmf --param iso -J 2 -r 16 -q -o %s", dir);
    CHECKF(rc == 0, "factor: rc %d: %s", rc, out);
    char path[4300], bad[4300], cmd[9000];
    snprintf(path, sizeof path, "%s/sampler.bin", dir);
    snprintf(bad, sizeof bad, "%s/bad/sampler.bin", dir);
    snprintf(cmd, sizeof cmd, "mkdir -p %s/bad", dir);
    CHECK(sb_run(cmd, NULL, 0) == 0);
    rc = run("info %s", path); /* iso: 33 x 2 texels, 2 J C + 1 layers (the half-vector rows' weights) */
    CHECKF(rc == 0 && strstr(out, "sampler tables") && strstr(out, "32 x 1, 13 layers: J = 2 terms x 3 channels") &&
               strstr(out, "GGX lobe 0.0625 (alpha 0.34999"),
           "rc %d: %s", rc, out);
    rc = run("info %s --json 2>/dev/null", path);
    CHECKF(rc == 0 && strstr(out, "\"kind\": \"sampler tables\"") && strstr(out, "\"lobe_share\": 0.0625") &&
               strstr(out, "\"half_rows\": true"),
           "rc %d: %s", rc, out);
    /* layer 6 holds the shares: s at (0, 1), s_l at (32, 1), alpha at (32, 0) */
    static const struct {
        uint32_t k, x, y;
        float v;
        const char *said;
    } cases[] = {{6, 32, 0, NAN, "layer 6, texel (32, 0): nan (not finite)"},
                 {6, 32, 1, 2.0f, "layer 6: GGX lobe share out of range"},
                 {6, 32, 0, 5.0f, "layer 6: GGX lobe alpha out of range"},
                 {6, 0, 1, 0.0f, "layer 6, texel (0, 1): cosine share 0 outside"},
                 {1, 3, 0, 1.5f, "layer 1: the row's CDF exceeds 1 at texel (3, 0)"},
                 {0, 0, 1, -1.0f, "layer 0, texel (0, 1): integral -1 is negative"},
                 {8, 2, 0, -1.0f, "layer 8, texel (2, 0): weight -1 is negative"},
                 /* the row cells' measures, by which the GLSL pdf divides, and texels written 0 that it
                    does not read (were described as whole; a weights layer's edge was read as the cosine
                    share of layer 12) */
                 {6, 3, 0, 0.0f, "layer 6, texel (3, 0): row cell measure 0 is not positive"},
                 {6, 3, 0, -1.0f, "layer 6, texel (3, 0): row cell measure -1 is not positive"},
                 {1, 5, 1, 0.5f, "layer 1, texel (5, 1): 0.5 in a CDF layer's row H past the integral"},
                 {12, 32, 0, 1.0f, "layer 12, texel (32, 0): 1 in a weights layer's column W"},
                 {9, 4, 1, 2.0f, "layer 9, texel (4, 1): 2 in a weights layer's row H"}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        CHECK(patch_texel(path, bad, cases[i].k, cases[i].x, cases[i].y, cases[i].v) == 0);
        rc = run("info %s 2>&1", bad);
        CHECKF(rc == 2 && strstr(out, cases[i].said), "case %zu: rc %d: %s", i, rc, out);
    }
    /* a column layout (vndf): its shares layer holds the shares alone */
    char vdir[4300], vpath[4400];
    snprintf(vdir, sizeof vdir, "%s/vndf", dir);
    snprintf(vpath, sizeof vpath, "%s/sampler.bin", vdir);
    rc = run("factor " SB_MEASURED_DIR "/rgl_paper_white_rgb.bsdf --method nmf --param vndf -J 1 -q -o %s", vdir);
    CHECKF(rc == 0 && run("info %s", vpath) == 0, "factor vndf: rc %d: %s", rc, out);
    CHECK(patch_texel(vpath, bad, 3, 4, 3, 0.7f) == 0);
    rc = run("info %s 2>&1", bad);
    CHECKF(rc == 2 && strstr(out, "layer 3, texel (4, 3): 0.699999988 in the shares layer of a column layout"),
           "vndf: rc %d: %s", rc, out);
    /* info DIR checks the set's sampler.bin (described the set, exit 0, with its sampler.bin damaged) */
    snprintf(cmd, sizeof cmd, "mkdir -p %s/set && cp %s/*.exr %s/report.json %s/sepbrdf.glsl %s/set/", dir, dir, dir,
             dir, dir);
    CHECK(sb_run(cmd, NULL, 0) == 0);
    char set[4400], setbin[4500];
    snprintf(set, sizeof set, "%s/set", dir);
    snprintf(setbin, sizeof setbin, "%s/sampler.bin", set);
    CHECK(patch_texel(path, setbin, 6, 3, 0, 0.0f) == 0);
    rc = run("info %s 2>&1", set);
    CHECKF(rc == 2 && strstr(out, "set/sampler.bin: layer 6, texel (3, 0): row cell measure 0"), "set: rc %d: %s", rc,
           out);
    CHECK(patch_texel(path, setbin, 6, 3, 0, texel_of(path, 6, 3, 0)) == 0);
    rc = run("info %s 2>&1", set);
    CHECKF(rc == 0 && strstr(out, "a factor set"), "whole set: rc %d: %s", rc, out);
    snprintf(cmd, sizeof cmd, "head -c -4 %s > %s", path, bad);
    CHECK(sb_run(cmd, NULL, 0) == 0);
    rc = run("info %s 2>&1", bad);
    CHECKF(rc == 2 && strstr(out, "holds 3452 bytes, its header's 33 x 2 texels x 13 layers need 3456"), "rc %d: %s",
           rc, out);
}
