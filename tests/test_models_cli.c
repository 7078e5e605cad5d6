/* CLI: `sepbrdf factor` with every model, every term choice and every
 * preset runs (the real binary SB_CLI) and writes its report. */
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

static char out[65536];

/* Run `SB_CLI factor SPEC --res 8 --terms 2 -q -o DIR/sub`; check the exit
 * code and report.json. */
static void factor_ok(const char *dir, const char *spec, int k) {
    char cmd[8192], sub[4096], path[4200];
    snprintf(sub, sizeof sub, "%s/%d", dir, k);
    snprintf(cmd, sizeof cmd, "%s factor '%s' --res 8 --terms 2 -q -o %s", SB_CLI, spec, sub);
    int rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 0, "%s: rc %d: %s", spec, rc, out);
    snprintf(path, sizeof path, "%s/report.json", sub);
    CHECKF(sb_file_exists(path), "%s: no %s", spec, path);
}

/* Every model with its defaults, and with every choice of every choice key. */
SB_TEST(factor_every_model) {
    const char *dir = sb_tmpdir("models-cli");
    int k = 0;
    for (size_t m = 0; m < sb_model_count(); m++) {
        const sb_model_info_t *mi = sb_model_at(m);
        factor_ok(dir, mi->name, k++);
        for (size_t j = 0; j < mi->key_count; j++) {
            const sb_model_key_t *key = &mi->keys[j];
            if (!strchr(key->range, '|')) continue; /* choice keys list their values as a|b|c */
            char values[256];
            snprintf(values, sizeof values, "%s", key->range);
            for (char *v = strtok(values, "|"); v; v = strtok(NULL, "|")) {
                char spec[512];
                snprintf(spec, sizeof spec, "%s:%s=%s", mi->name, key->name, v);
                if (!strcmp(key->name, "f") && !strcmp(v, "dielectric")) strcat(spec, ",ior=diamond");
                factor_ok(dir, spec, k++);
            }
        }
    }
    /* sharp and grazing-sensitive settings */
    static const char *const extra[] = {
        "phong:n=10000,guard=0",
        "modified-phong:n=10000,floor=0.001",
        "cook-torrance:roughness=0.001,g=none,guard=0",
        "cook-torrance:d=beckmann,denom=cos,g=vcavity,f=dielectric,ior=glass",
        "microfacet:base=0.9/0.5/0.2,metallic=0.5,reflectance=0.7,roughness=0.001",
    };
    for (size_t i = 0; i < sizeof extra / sizeof extra[0]; i++)
        factor_ok(dir, extra[i], k++);
}

/* Every preset where it is accepted: metals as base= and f0=, dielectrics
 * as ior= and f0=. */
SB_TEST(factor_every_preset) {
    const char *dir = sb_tmpdir("models-cli");
    int k = 0;
    for (size_t i = 0; i < sb_preset_count(); i++) {
        const sb_preset_t *p = sb_preset_at(i);
        char spec[512];
        if (p->ior > 0) {
            snprintf(spec, sizeof spec, "cook-torrance:f=dielectric,ior=%s", p->name);
            factor_ok(dir, spec, k++);
            snprintf(spec, sizeof spec, "cook-torrance:f=schlick,f0=%s", p->name);
            factor_ok(dir, spec, k++);
        } else {
            snprintf(spec, sizeof spec, "microfacet:base=%s,roughness=0.5", p->name);
            factor_ok(dir, spec, k++);
            snprintf(spec, sizeof spec, "cook-torrance:f=conductor,f0=%s", p->name);
            factor_ok(dir, spec, k++);
        }
    }
}

/* A bad spec names the key, exits 1 and writes nothing. */
SB_TEST(factor_bad_spec) {
    const char *dir = sb_tmpdir("models-cli");
    static const char *const bad[] = {"cook-torrance:d=nope", "phong:n=-1", "modified-phong:kd=abc",
                                      "microfacet:base=glass", "lambert:albedo=0.5,shininess=3"};
    static const char *const key[] = {"'d'", "'n'", "'kd'", "'base'", "'shininess'"};
    for (int i = 0; i < 5; i++) {
        char cmd[8192], sub[4096];
        snprintf(sub, sizeof sub, "%s/bad%d", dir, i);
        snprintf(cmd, sizeof cmd, "%s factor '%s' --res 8 --terms 2 -q -o %s", SB_CLI, bad[i], sub);
        CHECKF(sb_run(cmd, out, sizeof out) == 1, "%s", bad[i]);
        CHECKF(strstr(out, key[i]) != NULL, "%s: '%s'", bad[i], out);
        char path[4200];
        snprintf(path, sizeof path, "%s/report.json", sub);
        CHECK(!sb_file_exists(path));
    }
}

/* `sepbrdf list` prints every model, every key and every preset. */
SB_TEST(list_everything) {
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "%s list", SB_CLI);
    CHECK(sb_run(cmd, out, sizeof out) == 0);
    for (size_t m = 0; m < sb_model_count(); m++) {
        const sb_model_info_t *mi = sb_model_at(m);
        CHECKF(strstr(out, mi->name) != NULL, "list lacks %s", mi->name);
        for (size_t j = 0; j < mi->key_count; j++) {
            /* the meaning may be wrapped: check its first word run */
            char head[24];
            snprintf(head, sizeof head, "%s", mi->keys[j].meaning);
            CHECKF(strstr(out, head) != NULL, "list lacks %s.%s", mi->name, mi->keys[j].name);
            CHECKF(strstr(out, mi->keys[j].def) != NULL || strlen(mi->keys[j].def) > 40, "list lacks default of %s",
                   mi->keys[j].name);
        }
    }
    for (size_t i = 0; i < sb_preset_count(); i++)
        CHECKF(strstr(out, sb_preset_at(i)->name), "%s", sb_preset_at(i)->name);
    CHECK(strstr(out, "1.022") != NULL);
    snprintf(cmd, sizeof cmd, "%s list cook-torrance", SB_CLI);
    CHECK(sb_run(cmd, out, sizeof out) == 0);
    CHECK(strstr(out, "denom") != NULL && strstr(out, "lambert") == NULL);
    snprintf(cmd, sizeof cmd, "%s list nosuchmodel", SB_CLI);
    CHECK(sb_run(cmd, out, sizeof out) == 1);
    CHECK(strstr(out, "nosuchmodel") != NULL);
    snprintf(cmd, sizeof cmd, "%s list --bogus", SB_CLI);
    CHECK(sb_run(cmd, out, sizeof out) == 1);
    CHECK(strstr(out, "--bogus") != NULL);
}
