/* SPDX-License-Identifier: GPL-3.0-or-later */
/* `ftm bench net`: the session benchmark (docs/bench-net.md). Only built with
 * the wire layer (FTM_BUILD_WIRE), whose programs ftm-server and ftm-bot it
 * runs; it links neither DDS nor the wire layer itself. */
#ifndef FTM_TOOLS_BENCH_NET_H
#define FTM_TOOLS_BENCH_NET_H

int ftm_bench_net(int argc, char **argv);
/* `ftm bench tick`: the server's tick per training scene (bench_tick.c). */
int ftm_bench_tick(int argc, char **argv);

#endif
