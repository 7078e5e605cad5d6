/* sepbrdf list: every model with its keys, and every preset. */
#include <string.h>

#include "cli.h"

/* Print text wrapped at `width` columns, continuation lines indented by `indent`. */
static void print_wrapped(const char *text, int indent, int first_col, int width) {
    int col = first_col;
    const char *p = text;
    while (*p) {
        while (*p == ' ')
            p++;
        size_t w = strcspn(p, " ");
        if (!w) break;
        if (col > indent && col + 1 + (int)w > width) {
            printf("\n%*s", indent, "");
            col = indent;
        } else if (col > indent) {
            putchar(' ');
            col++;
        }
        printf("%.*s", (int)w, p);
        col += (int)w;
        p += w;
    }
    putchar('\n');
}

static void print_model(const sb_model_info_t *mi) {
    printf("\n  %s\n      ", mi->name);
    print_wrapped(mi->summary, 6, 6, 100);
    for (size_t k = 0; k < mi->key_count; k++) {
        const sb_model_key_t *key = &mi->keys[k];
        printf("    %-12s ", key->name);
        print_wrapped(key->meaning, 17, 17, 100);
        printf("%17s", "");
        char tail[512];
        snprintf(tail, sizeof tail, "range %s; default %s", key->range, key->def);
        print_wrapped(tail, 17, 17, 100);
    }
}

static void print_presets(void) {
    printf("\nPresets (metals: base=NAME or f0=NAME; dielectrics: ior=NAME or f0=NAME):\n");
    for (size_t i = 0; i < sb_preset_count(); i++) {
        const sb_preset_t *p = sb_preset_at(i);
        if (p->ior > 0)
            printf("  %-13s %-10s ior %-6.4g F0 = ((ior-1)/(ior+1))^2 = %.4f\n", p->name, p->kind, p->ior, p->f0[0]);
        else
            printf("  %-13s %-10s F0 (linear) %.3f %.3f %.3f\n", p->name, p->kind, p->f0[0], p->f0[1], p->f0[2]);
    }
}

int cmd_list(int argc, char **argv) {
    const char *what = NULL;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
            printf(
                "usage: sepbrdf list [MODEL | presets]\n\n"
                "Print every model, each key with its meaning, range and default,\n"
                "and every material preset (usable as base=NAME, f0=NAME or ior=NAME).\n"
                "With MODEL, print that model only; with `presets`, the presets only.\n\noptions:\n" CLI_VERBOSITY_HELP
                "\n" CLI_EXIT_HELP);
            return EXIT_OK;
        }
        if (cli_verbosity_opt(argv[i])) continue;
        if (argv[i][0] == '-' || what) {
            cli_error("list", argv[i][0] == '-' ? "unknown option '%s'" : "unexpected argument '%s'", argv[i]);
            return EXIT_USAGE;
        }
        what = argv[i];
    }
    if (what && strcmp(what, "presets") == 0) {
        print_presets();
        return EXIT_OK;
    }
    if (what) {
        for (size_t m = 0; m < sb_model_count(); m++)
            if (strcmp(sb_model_at(m)->name, what) == 0) {
                printf("SOURCE = %s[:key=value,...]; values: numbers, RGB r/g/b, preset names, or a|b choices\n", what);
                print_model(sb_model_at(m));
                return EXIT_OK;
            }
        cli_error("list", "unknown model '%s' (`sepbrdf list` shows them all)", what);
        return EXIT_USAGE;
    }
    printf("Models (SOURCE = MODEL[:key=value,...]; values: numbers, RGB r/g/b, preset names, or a|b choices).\n"
           "l points to the light, v to the viewer, n = z, r = 2 (n.l) n - l, h = (l + v)/|l + v|;\n"
           "f = 0 below the horizon.\n");
    for (size_t m = 0; m < sb_model_count(); m++)
        print_model(sb_model_at(m));
    print_presets();
    return EXIT_OK;
}
