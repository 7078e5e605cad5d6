/* sepbrdf list: every model with its keys, and every preset. */
#include <string.h>

#include "cli.h"

int cmd_list(int argc, char **argv) {
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
            printf("usage: sepbrdf list [OPTIONS]\n\nPrint every model, each key with its meaning, range and default,\n"
                   "and every material preset (usable as base=NAME, f0=NAME or ior=NAME).\n\noptions:\n"
                   CLI_VERBOSITY_HELP "\n" CLI_EXIT_HELP);
            return EXIT_OK;
        }
        if (cli_verbosity_opt(argv[i])) continue;
        cli_error("list", "unknown option '%s'", argv[i]);
        return EXIT_USAGE;
    }
    printf("Models (SOURCE = MODEL[:key=value,...]):\n");
    for (size_t m = 0; m < sb_model_count(); m++) {
        const sb_model_info_t *mi = sb_model_at(m);
        printf("\n  %s - %s\n", mi->name, mi->summary);
        for (size_t k = 0; k < mi->key_count; k++)
            printf("    %-12s %s\n    %-12s range %s, default %s\n", mi->keys[k].name, mi->keys[k].meaning, "",
                   mi->keys[k].range, mi->keys[k].def);
    }
    printf("\nPresets:\n");
    for (size_t i = 0; i < sb_preset_count(); i++) {
        const sb_preset_t *p = sb_preset_at(i);
        if (p->ior > 0)
            printf("  %-10s %-10s ior %.4g, F0 %.4f\n", p->name, p->kind, p->ior, p->f0[0]);
        else
            printf("  %-10s %-10s F0 (linear) %.3f %.3f %.3f\n", p->name, p->kind, p->f0[0], p->f0[1], p->f0[2]);
    }
    return EXIT_OK;
}
