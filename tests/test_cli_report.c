/* CLI: report.json of a real `factor` run against the key table of the
 * docs/report.md ("## report.json"), both ways, so that docs and output cannot
 * drift.  Runs the binary SB_CLI.
 *
 * Key paths: "a.b" is key b of object a, "a[]" an element of array a (its
 * keys "a[].k"); in that table, "x.{R,G,B}" stands for x.R, x.G, x.B. */
#include <stdlib.h>
#include <string.h>

#include "harness.h"

#define MAXKEYS 512
#define KEYLEN 128

typedef struct keyset {
    char k[MAXKEYS][KEYLEN];
    int n;
} keyset_t;

static void add_key(keyset_t *s, const char *k) {
    for (int i = 0; i < s->n; i++)
        if (strcmp(s->k[i], k) == 0) return;
    if (s->n < MAXKEYS) snprintf(s->k[s->n++], KEYLEN, "%.127s", k);
}

static int has_key(const keyset_t *s, const char *k) {
    for (int i = 0; i < s->n; i++)
        if (strcmp(s->k[i], k) == 0) return 1;
    return 0;
}

/* ---- a small JSON reader that records every key path ------------------- */

typedef struct reader {
    const char *p;
    int bad;
    keyset_t *keys;
} reader_t;

static void ws(reader_t *r) {
    while (*r->p == ' ' || *r->p == '\n' || *r->p == '\t' || *r->p == '\r')
        r->p++;
}

static void string(reader_t *r, char *out, size_t size) {
    size_t n = 0;
    if (*r->p != '"') {
        r->bad = 1;
        return;
    }
    r->p++;
    while (*r->p && *r->p != '"') {
        if (*r->p == '\\' && r->p[1]) r->p++;
        if (out && n + 1 < size) out[n++] = *r->p;
        r->p++;
    }
    if (*r->p != '"')
        r->bad = 1;
    else
        r->p++;
    if (out) out[n] = 0;
}

static void value(reader_t *r, const char *path);

static void object(reader_t *r, const char *path) {
    r->p++; /* { */
    ws(r);
    if (*r->p == '}') {
        r->p++;
        return;
    }
    while (!r->bad) {
        char key[KEYLEN], sub[2 * KEYLEN];
        ws(r);
        string(r, key, sizeof key);
        ws(r);
        if (*r->p != ':') {
            r->bad = 1;
            return;
        }
        r->p++;
        snprintf(sub, sizeof sub, "%s%s%s", path, *path ? "." : "", key);
        add_key(r->keys, sub);
        value(r, sub);
        ws(r);
        if (*r->p == ',') {
            r->p++;
            continue;
        }
        if (*r->p == '}') {
            r->p++;
            return;
        }
        r->bad = 1;
    }
}

static void array(reader_t *r, const char *path) {
    char sub[2 * KEYLEN];
    snprintf(sub, sizeof sub, "%s[]", path);
    r->p++; /* [ */
    ws(r);
    if (*r->p == ']') {
        r->p++;
        return;
    }
    while (!r->bad) {
        value(r, sub);
        ws(r);
        if (*r->p == ',') {
            r->p++;
            continue;
        }
        if (*r->p == ']') {
            r->p++;
            return;
        }
        r->bad = 1;
    }
}

static void value(reader_t *r, const char *path) {
    ws(r);
    if (*r->p == '{')
        object(r, path);
    else if (*r->p == '[')
        array(r, path);
    else if (*r->p == '"')
        string(r, NULL, 0);
    else if (strncmp(r->p, "true", 4) == 0)
        r->p += 4;
    else if (strncmp(r->p, "false", 5) == 0)
        r->p += 5;
    else if (strncmp(r->p, "null", 4) == 0)
        r->p += 4;
    else {
        char *end;
        strtod(r->p, &end);
        if (end == r->p) r->bad = 1;
        r->p = end;
    }
}

static char *slurp(const char *path) {
    FILE *fp = fopen(path, "rb");
    if (!fp) return NULL;
    fseek(fp, 0, SEEK_END);
    long n = ftell(fp);
    fseek(fp, 0, SEEK_SET);
    char *buf = malloc((size_t)n + 1);
    if (buf && fread(buf, 1, (size_t)n, fp) != (size_t)n) {
        free(buf);
        buf = NULL;
    }
    if (buf) buf[n] = 0;
    fclose(fp);
    return buf;
}

/* Keys of the docs/report.md table under "## report.json": the first `code` span
 * of each table row, with {a,b} expanded. */
static int readme_keys(keyset_t *s) {
    char *text = slurp(SB_SOURCE_DIR "/docs/report.md");
    if (!text) return -1;
    char *sec = strstr(text, "\n## report.json");
    if (!sec) {
        free(text);
        return -1;
    }
    sec++;
    char *end = strstr(sec + 3, "\n## ");
    if (end) *end = 0;
    for (char *line = sec; line && *line; line = strchr(line, '\n') ? strchr(line, '\n') + 1 : NULL) {
        if (strncmp(line, "| `", 3) != 0) continue;
        char key[KEYLEN];
        const char *a = line + 3, *b = strchr(a, '`');
        if (!b || (size_t)(b - a) >= sizeof key) continue;
        memcpy(key, a, (size_t)(b - a));
        key[b - a] = 0;
        char *lb = strchr(key, '{'), *rb = lb ? strchr(lb, '}') : NULL;
        if (!lb || !rb) {
            add_key(s, key);
            continue;
        }
        *lb = 0;
        *rb = 0;
        for (char *save = NULL, *alt = strtok_r(lb + 1, ",", &save); alt; alt = strtok_r(NULL, ",", &save)) {
            char full[2 * KEYLEN];
            snprintf(full, sizeof full, "%s%s%s", key, alt, rb + 1);
            add_key(s, full);
        }
    }
    free(text);
    return 0;
}

static keyset_t doc, rep;

SB_TEST(keys_documented) {
    CHECKF(readme_keys(&doc) == 0, "no \"## report.json\" section in %s/docs/report.md", SB_SOURCE_DIR);
    CHECKF(doc.n >= 20, "only %d keys in the docs/report.md table", doc.n);
    /* --param auto (the default) so that auto_tried is there too, a
     * measured table so that measured is, --warp adaptive (auto keeps
     * iso here) so that the warp tables are, and --budget (searched at the
     * given R and J only) so that budget is */
    const char *dir = sb_tmpdir("report");
    char cmd[4096], out[8192], path[4200];
    /* --cv-folds 2: every key is written, with the fewest refits */
    snprintf(cmd, sizeof cmd,
             "%s factor %s/data/example_gonio.csv --res 8 -J 3 --warp adaptive --budget 64K --cv-folds 2 -q -o %s",
             SB_CLI, SB_SOURCE_DIR, dir);
    int rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    snprintf(path, sizeof path, "%s/report.json", dir);
    char *json = slurp(path);
    CHECKF(json != NULL, "no %s", path);
    if (!json) return;
    reader_t r = {json, 0, &rep};
    value(&r, "");
    ws(&r);
    CHECKF(!r.bad && *r.p == 0, "report.json does not parse near: %.40s", r.p);
    free(json);
    for (int i = 0; i < doc.n; i++)
        CHECKF(has_key(&rep, doc.k[i]), "docs/report.md key `%s` missing in report.json", doc.k[i]);
    for (int i = 0; i < rep.n; i++)
        CHECKF(has_key(&doc, rep.k[i]), "report.json key `%s` is not documented in docs/report.md", rep.k[i]);
}

/* The reader and the table parser themselves, on a known text. */
SB_TEST(reader_paths) {
    keyset_t s;
    s.n = 0;
    reader_t r = {"{\"a\": {\"b\": [1, {\"c\": null}]}, \"d\": \"x\\\"y\", \"e\": [[true]]}", 0, &s};
    value(&r, "");
    CHECK(!r.bad);
    CHECK(has_key(&s, "a") && has_key(&s, "a.b") && has_key(&s, "a.b[].c") && has_key(&s, "d") && has_key(&s, "e"));
    CHECK(s.n == 5);
    reader_t bad = {"{\"a\" 1}", 0, &s};
    value(&bad, "");
    CHECK(bad.bad);
}

/* report.json's files name every file of the set the run wrote (its list,
 * sepbrdf-set-factor.txt, but report.json itself), and nothing else: an
 * RGL file's vndf fit with every translation (vndf.exr and sepbrdf.hlsl,
 * .metal, .wgsl were written but not named). */
SB_TEST(files_name_the_set) {
    const char *dir = sb_tmpdir("report_files");
    char cmd[4096], out[8192], path[4200];
    snprintf(cmd, sizeof cmd, "%s factor %s/rgl_chm_orange_rgb.bsdf --param vndf -J 1 --shader all -q -o %s", SB_CLI,
             SB_MEASURED_DIR, dir);
    int rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    snprintf(path, sizeof path, "%s/report.json", dir);
    char *json = slurp(path);
    snprintf(path, sizeof path, "%s/sepbrdf-set-factor.txt", dir);
    char *list = slurp(path);
    char *files = json ? strstr(json, "\"files\": {") : NULL, *end = files ? strchr(files, '}') : NULL;
    CHECKF(list && files && end, "no set list or no files object in %s", dir);
    if (!list || !files || !end) goto out;
    *end = 0; /* files holds no nested object */
    int listed = 0;
    for (char *save = NULL, *line = strtok_r(list, "\n", &save); line; line = strtok_r(NULL, "\n", &save)) {
        if (line[0] == '#' || strcmp(line, "report.json") == 0) continue;
        char quoted[300];
        snprintf(quoted, sizeof quoted, "\"%.290s\"", line);
        CHECKF(strstr(files, quoted), "the set holds %s, report.json's files do not name it: %s", line, files);
        listed++;
    }
    CHECKF(listed == 7, "%d files listed (g, h, glsl, vndf.exr, three translations)", listed);
    int named = 0; /* every file named is one of the set: count the names with a dot */
    for (const char *q = strchr(files, '"'); q; q = strchr(q + 1, '"')) {
        const char *e = strchr(q + 1, '"');
        if (!e) break;
        if (memchr(q + 1, '.', (size_t)(e - q - 1))) named++;
        q = e;
    }
    CHECKF(named == listed, "report.json's files name %d files, the set %d: %s", named, listed, files);
out:
    free(json);
    free(list);
}
