/* SPDX-License-Identifier: GPL-3.0-or-later */
/* `ftm mesh`: runs ftm-mesh, the scan-to-tissue-mesh program (tools/mesher:
 * C++, for CGAL), installed beside ftm. A separate program so that libftm
 * and ftm stay C and link no CGAL (docs/meshes.md). */
#include "commands.h"

#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

int ftm_cmd_mesh(int argc, char **argv)
{
#ifndef FTM_HAVE_MESHER
    (void)argc;
    (void)argv;
    fprintf(stderr, "ftm mesh: this ftm was built without ftm-mesh, the meshing program: it "
                    "needs CGAL (Debian: libcgal-dev) and a C++ compiler when FTM is configured "
                    "(docs/meshes.md)\n");
    return 2;
#else
    char self[PATH_MAX], path[PATH_MAX + 16];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n <= 0) {
        fprintf(stderr, "ftm mesh: cannot find where ftm is (/proc/self/exe): %s\n",
                strerror(errno));
        return 2;
    }
    self[n] = '\0';
    char *slash = strrchr(self, '/');
    *slash = '\0';
    snprintf(path, sizeof path, "%s/ftm-mesh", self);
    char **args = calloc((size_t)argc + 1, sizeof *args);
    if (!args)
        return 2;
    args[0] = path;
    for (int i = 1; i < argc; i++)
        args[i] = argv[i];
    fflush(NULL);
    execv(path, args);
    fprintf(stderr, "ftm mesh: cannot run %s: %s (ftm-mesh is installed beside ftm)\n", path,
            strerror(errno));
    free(args);
    return 2;
#endif
}
