/* The viewer page in a real browser, shared by the viewer's tests
 * (test_view.c: the sphere; test_view3d.c: the lobe and the sky): open
 * file://PAGE?QUERY in headless Chromium, read its test output back. */
#ifndef SB_VIEW_PAGE_H
#define SB_VIEW_PAGE_H

#include <stddef.h>
#include <stdlib.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

/* Chromium: $SB_CHROMIUM, else chromium or chromium-browser on PATH; NULL none. */
const char *view_browser(void);

/* Skip the case without a browser, except in CI (CI set), where it fails. */
#define NEED_BROWSER()                                                                                                 \
    do {                                                                                                               \
        if (!view_browser()) {                                                                                         \
            CHECKF(!getenv("CI"), "no chromium in CI: scripts/setup-deps.sh installs it");                             \
            SKIP("no chromium (Debian: apt-get install chromium, or scripts/setup-deps.sh): browser cases skipped");   \
        }                                                                                                              \
    } while (0)

/* Open file://PAGE?QUERY headless, no network, a fresh profile; the DOM
 * into *dom (malloc'ed), the browser's log into log.  0 on success. */
int view_open_page(const char *page, const char *query, char **dom, char *log, size_t log_size);

/* The first console message other than the GL driver's performance notes;
 * NULL when none. */
const char *view_console_error(const char *log);

/* base64 of little-endian float32 from p: malloc'ed, *count floats. */
float *view_b64_floats(const char *p, size_t *count);

/* Line "KEY=BASE64" of the test output: float32 RGBA, W x H, rows from the
 * top, into an image (alpha > 0.5: covered).  0 on success. */
int view_decode_image(const char *text, const char *key, size_t w, size_t h, sb_image_t *img);

/* DIR/index.html?QUERY in test mode: 0 when the page said status=ok and
 * the browser logged no console error, *text its test output (malloc'ed,
 * lines KEY=VALUE); else status says why not and *text is NULL. */
int view_page_run(const char *dir, const char *query, char *status, size_t status_size, char **text);

/* `sepbrdf factor ARGS -o DIR -q`, then `sepbrdf view DIR`; DIR returned
 * (static), NULL on failure (reported). */
const char *view_make_folder(const char *args);

/* Display PSNR of b against a, exposure from a's brightest channel (as
 * `sepbrdf render` and the GL test do); -1 when they cannot be compared. */
double view_psnr(const sb_image_t *a, const sb_image_t *b);

#endif
