/* The viewer page in a real browser (view_page.h). */
#include "view_page.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* ---- the browser ------------------------------------------------------- */

const char *view_browser(void) {
    static char path[4096];
    const char *env = getenv("SB_CHROMIUM");
    if (env && *env) return env;
    const char *dirs = getenv("PATH");
    if (!dirs) return NULL;
    static const char *const names[] = {"chromium", "chromium-browser"};
    for (int k = 0; k < 2; k++)
        for (const char *d = dirs; *d;) {
            size_t n = strcspn(d, ":");
            snprintf(path, sizeof path, "%.*s/%s", (int)n, d, names[k]);
            if (access(path, X_OK) == 0) return path;
            d += n + (d[n] == ':');
        }
    return NULL;
}

/* Open file://PAGE?QUERY headless, no network, a fresh profile; the DOM
 * into *dom (malloc'ed), the browser's log into log.  0 on success. */
int view_open_page(const char *page, const char *query, char **dom, char *log, size_t log_size) {
    char tmp[4096], cmd[16384], path[4200];
    snprintf(tmp, sizeof tmp, "%s", sb_tmpdir("chromium"));
    snprintf(cmd, sizeof cmd,
             "timeout 120 '%s' --headless --no-sandbox --disable-gpu --disable-quic --no-first-run "
             "--disable-background-networking --disable-component-update --disable-sync --enable-unsafe-swiftshader "
             "--user-data-dir='%s/profile' --enable-logging=stderr --v=0 --dump-dom 'file://%s%s%s' > '%s/dom' "
             "2> '%s/log'",
             view_browser(), tmp, page, query ? "?" : "", query ? query : "", tmp, tmp);
    int rc = system(cmd);
    *dom = NULL;
    snprintf(path, sizeof path, "%s/log", tmp);
    FILE *fp = fopen(path, "rb");
    size_t n = fp ? fread(log, 1, log_size - 1, fp) : 0;
    log[n] = 0;
    if (fp) fclose(fp);
    snprintf(path, sizeof path, "%s/dom", tmp);
    if ((fp = fopen(path, "rb"))) {
        fseek(fp, 0, SEEK_END);
        long len = ftell(fp);
        fseek(fp, 0, SEEK_SET);
        if (len > 0 && (*dom = malloc((size_t)len + 1))) {
            n = fread(*dom, 1, (size_t)len, fp);
            (*dom)[n] = 0;
        }
        fclose(fp);
    }
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmp);
    if (system(cmd) != 0) fprintf(stderr, "cannot remove %s\n", tmp);
    return rc == 0 && *dom ? 0 : -1;
}

/* Console messages other than the GL driver's performance notes (the
 * test mode's readPixels stalls the pipeline, and says so). */
const char *view_console_error(const char *log) {
    for (const char *p = strstr(log, "CONSOLE"); p; p = strstr(p + 1, "CONSOLE")) {
        const char *eol = strchr(p, '\n');
        size_t n = eol ? (size_t)(eol - p) : strlen(p);
        char line[1024];
        snprintf(line, sizeof line, "%.*s", (int)n, p);
        if (!strstr(line, "GL Driver Message (OpenGL, Performance")) return p;
    }
    return strstr(log, "Uncaught");
}

/* ---- the page's test output -------------------------------------------- */

static int b64val(int c) {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    return c == '+' ? 62 : c == '/' ? 63 : -1;
}

/* base64 of little-endian float32 from p up to the first character that
 * is not base64: malloc'ed, *count floats; NULL on none. */
float *view_b64_floats(const char *p, size_t *count) {
    size_t len = 0;
    while (b64val(p[len]) >= 0)
        len++;
    size_t nbytes = len * 6 / 8, k = 0;
    unsigned char *bytes = malloc(nbytes + 4);
    float *out = malloc(nbytes + 4);
    uint32_t acc = 0;
    int bits = 0;
    for (size_t i = 0; bytes && i < len; i++) {
        acc = acc << 6 | (uint32_t)b64val(p[i]);
        if ((bits += 6) >= 8) bytes[k++] = (unsigned char)(acc >> (bits -= 8));
    }
    *count = k / 4;
    for (size_t i = 0; bytes && out && i < *count; i++) {
        uint32_t u = 0;
        for (int b = 0; b < 4; b++)
            u |= (uint32_t)bytes[i * 4 + b] << (8 * b);
        memcpy(&out[i], &u, 4);
    }
    free(bytes);
    if (!out || *count == 0) {
        free(out);
        return NULL;
    }
    return out;
}

/* Line "KEY=BASE64" of the test output: float32 RGBA, rows from the top,
 * into an image (alpha > 0.5: covered).  0 on success. */
int view_decode_image(const char *text, const char *key, size_t w, size_t h, sb_image_t *img) {
    char pat[32];
    size_t n = 0;
    snprintf(pat, sizeof pat, "\n%s=", key);
    const char *p = strstr(text, pat);
    float *px = p ? view_b64_floats(p + strlen(pat), &n) : NULL;
    int ok = px && n == w * h * 4 && sb_image_alloc(NULL, w, h, img) == SB_OK;
    for (size_t i = 0; ok && i < w * h; i++) {
        for (int c = 0; c < 3; c++)
            img->rgb[i * 3 + c] = px[i * 4 + c];
        img->mask[i] = px[i * 4 + 3] > 0.5f;
    }
    free(px);
    return ok ? 0 : -1;
}

/* DIR/index.html?QUERY in test mode: 0 when the page said status=ok and
 * the browser logged no console error, *text its test output (malloc'ed);
 * else status says why not, *text NULL. */
int view_page_run(const char *dir, const char *query, char *status, size_t status_size, char **text) {
    char page[4200], log[1 << 15];
    char *dom = NULL;
    *text = NULL;
    snprintf(page, sizeof page, "%s/index.html", dir);
    int rc = view_open_page(page, query, &dom, log, sizeof log);
    const char *t = dom ? strstr(dom, "id=\"sb-test\"") : NULL;
    t = t ? strchr(t, '>') : NULL;
    if (rc != 0 || !t) {
        snprintf(status, status_size, "browser failed (exit %d): %.300s", rc, log);
    } else {
        snprintf(status, status_size, "%.*s", (int)strcspn(t + 1, "\n<"), t + 1);
        const char *err = view_console_error(log);
        if (strcmp(status, "status=ok") == 0 && err) snprintf(status, status_size, "console: %.300s", err);
        if (strcmp(status, "status=ok") == 0) *text = strdup(t);
    }
    free(dom);
    return *text ? 0 : -1;
}

/* `sepbrdf factor ARGS -o DIR -q`, then `sepbrdf view DIR`; DIR returned
 * (static), NULL on failure (reported). */
const char *view_make_folder(const char *args) {
    static char g_out[1 << 16];
    static char dir[4096];
    char cmd[20000];
    snprintf(dir, sizeof dir, "%s", sb_tmpdir("view"));
    snprintf(cmd, sizeof cmd, "%s factor %s -o '%s' -q && %s view '%s' -q", SB_CLI, args, dir, SB_CLI, dir);
    int rc = sb_run(cmd, g_out, sizeof g_out);
    CHECKF(rc == 0, "factor %s + view: exit %d: %s", args, rc, g_out);
    return rc == 0 ? dir : NULL;
}

double view_psnr(const sb_image_t *a, const sb_image_t *b) {
    double peak = sb_image_max(a);
    sb_tonemap_t tm = {peak > 0 ? 1 / peak : 1, SB_TONEMAP_CLAMP};
    sb_image_diff_t d;
    if (sb_image_compare(NULL, a, b, &tm, &d) != SB_OK) return -1;
    return d.psnr;
}
