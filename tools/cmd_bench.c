/* SPDX-License-Identifier: GPL-3.0-or-later */
/* `ftm bench NAME`: benchmark programs. Each prints a table (or JSON with
 * --json) of medians measured in one run. */
#include "bench.h"
#include "commands.h"
#ifdef FTM_HAVE_NET
#include "bench_net.h"
#endif

#include <stdio.h>
#include <string.h>

static const struct {
    const char *name;
    int (*run)(int argc, char **argv);
    const char *what;
} benches[] = {
    {"table3", ftm_bench_table3, "paper Table 3: 50x50 2D lattice, step and search time per depth"},
    {"peers", ftm_bench_peers, "FTM against Bullet's soft body: the same bodies, step time"},
#ifdef FTM_HAVE_NET
    {"net", ftm_bench_net, "a loopback DDS session: tick rate, bytes per tick, latency vs ddsperf"},
    {"tick", ftm_bench_tick, "the server's tick per training scene and trainee count"},
#endif
#ifdef FTM_HAVE_FEM
    {"accuracy", ftm_bench_accuracy, "run time against error to equilibrium vs the FEM reference"},
    {"feel", ftm_bench_feel, "what a trainee feels: force and dent per model, far field, depth"},
#endif
};

static void usage(FILE *f)
{
    fprintf(f, "usage: ftm bench NAME [options]\n\nbenchmarks:\n");
    for (size_t i = 0; i < sizeof benches / sizeof benches[0]; i++)
        fprintf(f, "  %-10s %s\n", benches[i].name, benches[i].what);
    fprintf(f, "\nrun `ftm bench NAME --help` for a benchmark's options\n");
}

int ftm_cmd_bench(int argc, char **argv)
{
    if (argc < 2 || strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0) {
        usage(argc < 2 ? stderr : stdout);
        return argc < 2 ? 2 : 0;
    }
    for (size_t i = 0; i < sizeof benches / sizeof benches[0]; i++)
        if (strcmp(argv[1], benches[i].name) == 0)
            return benches[i].run(argc - 1, argv + 1);
    fprintf(stderr, "ftm bench: unknown benchmark '%s'\n", argv[1]);
    usage(stderr);
    return 2;
}
