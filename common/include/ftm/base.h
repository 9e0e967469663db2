/* FTM base types: vectors, status codes, error reports, logging hook.
 *
 * Every fallible call returns an int: FTM_OK (0) or a negative FTM_E* code.
 * Calls that can fail for a reason worth explaining also take an ftm_error*
 * (may be NULL) that receives a message naming what and where, e.g.
 * "liver.obj:17: face index 912 out of range (file has 400 vertices)".
 * On error no output parameter is written. */
#ifndef FTM_BASE_H
#define FTM_BASE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct ftm_vec3 {
    double x, y, z;
} ftm_vec3;

enum {
    FTM_OK = 0,
    FTM_EINVAL = -1,    /* a parameter is out of range or inconsistent */
    FTM_ENOMEM = -2,    /* allocation failed */
    FTM_EIO = -3,       /* a file could not be opened or read */
    FTM_EPARSE = -4,    /* malformed input file or text */
    FTM_ERANGE = -5,    /* an index or count is out of range */
    FTM_EUNSTABLE = -6, /* the integrator diverged and could not recover */
    FTM_ENOENT = -7,    /* a named thing (scene, generator, subcommand) is unknown */
};

/* Short description of a status code; never NULL. */
const char *ftm_strerror(int code);

#define FTM_ERROR_MESSAGE_MAX 512

typedef struct ftm_error {
    int code;                            /* FTM_OK or a negative code */
    char message[FTM_ERROR_MESSAGE_MAX]; /* human-readable, names file/line or parameter */
} ftm_error;

typedef enum ftm_log_level {
    FTM_LOG_DEBUG = 0,
    FTM_LOG_INFO = 1,
    FTM_LOG_WARN = 2,
    FTM_LOG_ERROR = 3,
} ftm_log_level;

/* Optional log sink. The core has no globals, so each object that can log
 * takes one of these in its definition struct; NULL means silent. */
typedef void (*ftm_log_fn)(void *user, ftm_log_level level, const char *message);

#ifdef __cplusplus
}
#endif
#endif
