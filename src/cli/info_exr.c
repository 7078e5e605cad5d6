/* sepbrdf info on a factor file: the header of one EXR written by
 * sb_factors_write_exr (attributes listed in exr.h), read with OpenEXRCore
 * directly so that one file is enough; sigma_j of the other terms come from
 * the headers of the sibling g files when they are there. */
#include <openexr.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli.h"
#include "sepbrdf/exr.h"

#define PREFIX "sepbrdf."

/* OpenEXRCore prints to stderr unless given a handler; keep the first
 * message for our own. */
static char exr_msg[256];
static void on_exr_error(exr_const_context_t c, exr_result_t code, const char *msg) {
    (void)c;
    if (!exr_msg[0]) snprintf(exr_msg, sizeof exr_msg, "%s", msg ? msg : exr_get_error_code_as_string(code));
}

static exr_result_t open_header(const char *path, exr_context_t *ex) {
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = on_exr_error;
    exr_msg[0] = 0;
    struct stat st;
    if (stat(path, &st) == 0 && !S_ISREG(st.st_mode)) { /* OpenEXR would wait on a FIFO */
        snprintf(exr_msg, sizeof exr_msg, "not a regular file (a device, FIFO or folder is not read)");
        return EXR_ERR_FILE_ACCESS;
    }
    /* as the textures' reader (exr.c): a damaged offset table is refused,
     * not rebuilt by scanning the file (info described such a file as
     * whole, exit 0, where render refused it) */
    init.flags = EXR_CONTEXT_FLAG_DISABLE_CHUNK_RECONSTRUCTION;
    return exr_start_read(ex, path, &init);
}

static const exr_attribute_t *attr(exr_context_t ex, const char *name, exr_attribute_type_t type) {
    const exr_attribute_t *a = NULL;
    if (exr_get_attribute_by_name(ex, 0, name, &a) != EXR_ERR_SUCCESS || !a || a->type != type) return NULL;
    return a;
}

static const char *attr_str(exr_context_t ex, const char *key) {
    const exr_attribute_t *a = attr(ex, key, EXR_ATTR_STRING);
    return a && a->string && a->string->str ? a->string->str : NULL;
}

static int attr_int(exr_context_t ex, const char *key, int32_t *out) {
    const exr_attribute_t *a = attr(ex, key, EXR_ATTR_INT);
    if (a) *out = a->i;
    return a != NULL;
}

static const exr_attr_float_vector_t *attr_floats(exr_context_t ex, const char *key) {
    const exr_attribute_t *a = attr(ex, key, EXR_ATTR_FLOAT_VECTOR);
    return a ? a->floatvector : NULL;
}

static const char *compression_name(exr_compression_t c) {
    static const char *const names[] = {"none", "RLE", "ZIPS", "ZIP", "PIZ", "PXR24", "B44", "B44A", "DWAA", "DWAB"};
    return (unsigned)c < sizeof names / sizeof names[0] ? names[c] : "?";
}

static const char *pixel_name(exr_pixel_type_t t) {
    switch (t) {
    case EXR_PIXEL_HALF:
        return "half";
    case EXR_PIXEL_FLOAT:
        return "float32";
    case EXR_PIXEL_UINT:
        return "uint32";
    default:
        return "?";
    }
}

/* Folder part of path ("." when none) into buf. */
static void dir_of(const char *path, char *buf, size_t size) {
    const char *slash = strrchr(path, '/');
    if (!slash)
        snprintf(buf, size, ".");
    else if (slash == path)
        snprintf(buf, size, "/");
    else
        snprintf(buf, size, "%.*s", (int)(slash - path), path);
}

/* sigma of every term from the g files next to `path`; this file's own
 * term from its header. */
static void print_sigmas(FILE *out, const char *path, exr_context_t self, int32_t term, int32_t terms, int32_t channels,
                         const char *const *cn) {
    char dir[4096], name[64], sib[4200];
    dir_of(path, dir, sizeof dir);
    fprintf(out, "  sigma_j    %4s", "j");
    for (int32_t c = 0; c < channels; c++)
        fprintf(out, "  %12s", cn[c]);
    fputc('\n', out);
    for (int32_t k = 0; k < terms; k++) {
        exr_context_t ex = NULL;
        const exr_attr_float_vector_t *s = NULL;
        if (k == term) {
            s = attr_floats(self, PREFIX "sigma");
        } else {
            sb_exr_name(SB_SIDE_G, (size_t)k, name, sizeof name);
            snprintf(sib, sizeof sib, "%s/%s", dir, name);
            if (open_header(sib, &ex) == EXR_ERR_SUCCESS) {
                int32_t t = -1;
                if (attr_int(ex, PREFIX "term", &t) && t == k) s = attr_floats(ex, PREFIX "sigma");
            }
        }
        fprintf(out, "             %4d", (int)k);
        for (int32_t c = 0; c < channels; c++) {
            if (s && c < s->length)
                fprintf(out, "  %12.6g", (double)s->arr[c]);
            else
                fprintf(out, "  %12s", "?");
        }
        fputc('\n', out);
        if (ex) exr_finish(&ex);
    }
}

/* Attribute i (sorted order) when it is a string the writer copied from
 * the factors' metadata (sepbrdf.*, but version and side): its key without
 * the prefix and its value; 0 otherwise. */
static int copied_attr(exr_context_t ex, int32_t i, const char **key, const char **value) {
    const exr_attribute_t *a = NULL;
    if (exr_get_attribute_by_index(ex, 0, EXR_ATTR_LIST_SORTED_ORDER, i, &a) != EXR_ERR_SUCCESS || !a) return 0;
    if (a->type != EXR_ATTR_STRING || strncmp(a->name, PREFIX, strlen(PREFIX)) != 0) return 0;
    *key = a->name + strlen(PREFIX);
    *value = a->string && a->string->str ? a->string->str : "";
    return strcmp(*key, "version") != 0 && strcmp(*key, "side") != 0;
}

/* The texture as one JSON object; within a set's (set: its folder) the
 * set, its report.json (null when missing) and the texture. */
static void exr_json(FILE *out, const char *path, const char *set, exr_context_t ex, int32_t term, int32_t terms,
                     int32_t channels) {
    json_t j = {out, 0, {0}};
    json_begin_object(&j, NULL);
    if (set) {
        char rep[4200];
        snprintf(rep, sizeof rep, "%s/report.json", set);
        json_string(&j, "file", set);
        json_string(&j, "kind", "factor set");
        json_string(&j, "report", access(rep, F_OK) == 0 ? rep : NULL);
        json_begin_object(&j, "texture");
    }
    json_string(&j, "file", path);
    json_string(&j, "kind", "factor texture");
    json_string(&j, "version", attr_str(ex, PREFIX "version"));
    json_string(&j, "side", attr_str(ex, PREFIX "side"));
    json_int(&j, "term", term);
    json_int(&j, "terms", terms);
    exr_attr_box2i_t dw;
    memset(&dw, 0, sizeof dw);
    if (exr_get_data_window(ex, 0, &dw) != EXR_ERR_SUCCESS) dw.max.x = dw.max.y = -1;
    json_int(&j, "width", (long long)(dw.max.x - dw.min.x + 1));
    json_int(&j, "height", (long long)(dw.max.y - dw.min.y + 1));
    json_int(&j, "channels", channels);
    const exr_attribute_t *sc = attr(ex, PREFIX "scale", EXR_ATTR_FLOAT);
    json_number(&j, "scale", sc ? (double)sc->f : 1.0);
    json_begin_object(&j, "attributes"); /* the string attributes, as the table lists them */
    int32_t count = 0;
    exr_get_attribute_count(ex, 0, &count);
    for (int32_t i = 0; i < count; i++) {
        const char *key, *value;
        if (copied_attr(ex, i, &key, &value)) json_string(&j, key, value);
    }
    json_end_object(&j);
    const char *arrays[2][2] = {{"sigma", PREFIX "sigma"}, {"rel_rms", PREFIX "rel_rms"}};
    for (int k = 0; k < 2; k++) { /* sigma: this term's, per channel; rel_rms per J' */
        const exr_attr_float_vector_t *v = attr_floats(ex, arrays[k][1]);
        json_begin_array(&j, arrays[k][0]);
        for (int32_t i = 0; v && i < v->length; i++)
            json_number(&j, NULL, (double)v->arr[i]);
        json_end_array(&j);
    }
    if (set) json_end_object(&j);
    json_end_object(&j);
}

/* An EXR's size, channel list and compression (-1 x -1, none when unread). */
typedef struct exr_shape {
    long long w, h;
    const exr_attr_chlist_t *chl;
    exr_compression_t comp;
} exr_shape_t;
static exr_shape_t exr_shape(exr_context_t ex) {
    exr_attr_box2i_t dw;
    memset(&dw, 0, sizeof dw);
    if (exr_get_data_window(ex, 0, &dw) != EXR_ERR_SUCCESS) dw.max.x = dw.max.y = -1;
    exr_shape_t s = {dw.max.x - dw.min.x + 1, dw.max.y - dw.min.y + 1, NULL, EXR_COMPRESSION_NONE};
    exr_get_channels(ex, 0, &s.chl);
    exr_get_compression(ex, 0, &s.comp);
    return s;
}

/* Whether every chunk of a scanline file's pixel data lies within the
 * file (info reads the header alone, and a file cut after it was described
 * as whole); tiled files are not checked.  On failure why says where. */
static int chunks_complete(exr_context_t ex, const char *path, char *why, size_t size) {
    exr_storage_t storage;
    struct stat st;
    if (exr_get_storage(ex, 0, &storage) != EXR_ERR_SUCCESS || storage != EXR_STORAGE_SCANLINE) return 1;
    if (stat(path, &st) != 0) return 1; /* open_header read it: a race, left to the readers */
    exr_attr_box2i_t dw;
    int32_t lines = 0;
    if (exr_get_data_window(ex, 0, &dw) != EXR_ERR_SUCCESS || exr_get_scanlines_per_chunk(ex, 0, &lines) != 0 ||
        lines < 1)
        return 1;
    for (int64_t y = dw.min.y; y <= dw.max.y; y += lines) {
        exr_chunk_info_t ci;
        if (exr_read_scanline_chunk_info(ex, 0, (int)y, &ci) != EXR_ERR_SUCCESS) {
            snprintf(why, size,
                     "the pixel data of scanline %lld cannot be located (the file is cut short or damaged%s%s)",
                     (long long)y, exr_msg[0] ? ": " : "", exr_msg);
            return 0;
        }
        if (ci.data_offset + ci.packed_size > (uint64_t)st.st_size) {
            snprintf(why, size, "the file is cut short: the pixel data of scanline %lld ends at byte %llu of %lld",
                     (long long)y, (unsigned long long)(ci.data_offset + ci.packed_size), (long long)st.st_size);
            return 0;
        }
    }
    return 1;
}

/* vndf.exr, the tables `factor` writes beside an RGL file's vndf fit (the
 * snippet reads it by texel): known by its sepbrdf.kind under any name, or
 * by its name where an earlier version wrote it without attributes. */
static int is_tables_exr(const char *path, exr_context_t ex) {
    const char *kind = attr_str(ex, PREFIX "kind");
    if (kind) return strcmp(kind, SB_EXR_KIND_VNDF_TABLES) == 0;
    const char *base = strrchr(path, '/');
    return strcmp(base ? base + 1 : path, "vndf.exr") == 0;
}
static int info_tables(const char *path, FILE *out, int json, exr_context_t ex) {
    exr_shape_t sh = exr_shape(ex);
    const exr_attr_chlist_t *chl = sh.chl;
    int nch = chl ? chl->num_channels : 0;
    if (json) {
        json_t j = {out, 0, {0}};
        json_begin_object(&j, NULL);
        json_string(&j, "file", path);
        json_string(&j, "kind", "vndf tables");
        json_int(&j, "width", sh.w);
        json_int(&j, "height", sh.h);
        json_int(&j, "channels", nch);
        json_string(&j, "compression", compression_name(sh.comp));
        json_end_object(&j);
        return EXIT_OK;
    }
    fprintf(out,
            "%s: sepbrdf vndf tables (an RGL file's VNDF, NDF and sigma tables, which the vndf layout's "
            "snippet reads as sb_vndf, by texel)\n",
            path);
    fprintf(out, "  size       %lld x %lld texels\n", sh.w, sh.h);
    fprintf(out, "  channels   %d:", nch);
    for (int i = 0; i < nch; i++)
        fprintf(out, " %s (%s)", chl->entries[i].name.str, pixel_name(chl->entries[i].pixel_type));
    fprintf(out, ", %s compression\n", compression_name(sh.comp));
    return EXIT_OK;
}

/* Whether a factor texture's pixels decode as render reads them (OpenEXR
 * takes an unknown compression byte for another method and fails only
 * there); the reader's message on stderr when not. */
static int pixels_decode(const char *path) {
    sb_context_t *ctx = NULL;
    sb_result_t r = sb_context_create(&ctx);
    if (r == SB_OK) r = sb_exr_texture_check(ctx, path);
    if (r != SB_OK)
        cli_error("info", "%s", ctx && sb_context_last_error(ctx) ? sb_context_last_error(ctx) : sb_result_message(r));
    sb_context_destroy(ctx);
    return r == SB_OK;
}

int info_exr(const char *path, FILE *out, int json, const char *set) {
    exr_context_t ex = NULL;
    exr_result_t rv = open_header(path, &ex);
    if (rv != EXR_ERR_SUCCESS) {
        cli_error("info", "%s: cannot read as an EXR file: %s", path,
                  exr_msg[0] ? exr_msg : exr_get_error_code_as_string(rv));
        if (ex) exr_finish(&ex);
        return EXIT_IO;
    }
    char why[640];
    exr_msg[0] = 0;
    if (!chunks_complete(ex, path, why, sizeof why)) {
        cli_error("info", "%s: %s", path, why);
        exr_finish(&ex);
        return EXIT_IO;
    }
    const char *version = attr_str(ex, PREFIX "version"), *side = attr_str(ex, PREFIX "side");
    int32_t term = 0, terms = 0, channels = 0;
    if (!version || !side || !attr_int(ex, PREFIX "term", &term) || !attr_int(ex, PREFIX "terms", &terms) ||
        !attr_int(ex, PREFIX "channels", &channels) || terms < 1 || term < 0 || term >= terms || channels < 1 ||
        channels > 3) {
        if (!set && is_tables_exr(path, ex)) {
            int rc = info_tables(path, out, json, ex);
            exr_finish(&ex);
            return rc;
        }
        cli_error("info", "%s: not a factor file (an EXR without the sepbrdf.* attributes `factor` writes)", path);
        exr_finish(&ex);
        return EXIT_IO;
    }
    if (!pixels_decode(path)) {
        exr_finish(&ex);
        return EXIT_IO;
    }
    if (json) {
        exr_json(out, path, set, ex, term, terms, channels);
        exr_finish(&ex);
        return EXIT_OK;
    }
    exr_shape_t sh = exr_shape(ex);
    const exr_attr_chlist_t *chl = sh.chl;
    static const char *const rgb[3] = {"R", "G", "B"}, *const y[1] = {"Y"};
    const char *const *cn = channels == 1 ? y : rgb;
    const char *param = attr_str(ex, PREFIX "param");

    fprintf(out, "%s: sepbrdf factor texture (written by sepbrdf %s)\n", path, version);
    fprintf(out, "  texture    %s_%02d (%s domain), term %d of J = %d\n", side, (int)term,
            strcmp(side, "h") == 0 ? "h, column" : "g, row", (int)term, (int)terms);
    fprintf(out, "  size       %lld x %lld texels", sh.w, sh.h);
    if (param && strstr(param, "res=")) fprintf(out, ", R = %d", atoi(strstr(param, "res=") + 4));
    fputc('\n', out);
    fprintf(out, "  channels   %d:", (int)channels);
    for (int i = 0; chl && i < chl->num_channels; i++)
        fprintf(out, " %s (%s)", chl->entries[i].name.str, pixel_name(chl->entries[i].pixel_type));
    const exr_attribute_t *sc = attr(ex, PREFIX "scale", EXR_ATTR_FLOAT);
    if (sc) fprintf(out, ", value = stored x %g", (double)sc->f);
    fprintf(out, ", %s compression\n", compression_name(sh.comp));
    /* every string attribute the writer copied from the factors' metadata */
    int32_t count = 0;
    exr_get_attribute_count(ex, 0, &count);
    for (int32_t i = 0; i < count; i++) {
        const char *key, *value;
        if (copied_attr(ex, i, &key, &value)) fprintf(out, "  %-10s %s\n", key, value);
    }
    print_sigmas(out, path, ex, term, terms, channels, cn);
    const exr_attr_float_vector_t *rel = attr_floats(ex, PREFIX "rel_rms");
    fprintf(out, "  rel_rms    %4s  %12s   (||M - M_J'||_F / ||M||_F, all channels)\n", "J'", "error");
    for (int32_t k = 0; rel && k < rel->length; k++)
        fprintf(out, "             %4d  %12.6g\n", (int)k + 1, (double)rel->arr[k]);
    if (!rel) fprintf(out, "             (none in this file)\n");
    exr_finish(&ex);
    return EXIT_OK;
}
