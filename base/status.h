/* status.h: the project's status codes. Functions return 0 (PF_OK) on success
 * and a negative pf_status on failure; pf_strerror() names each one.
 * "Try again / timed out" is kept apart from "malformed input". */
#ifndef PF_STATUS_H
#define PF_STATUS_H

#define PF_STATUS_LIST(X)                                          \
    X(PF_OK,           0, "success")                               \
    X(PF_ENOMEM,      -1, "out of memory")                         \
    X(PF_EIO,         -2, "input/output error")                    \
    X(PF_EPARSE,      -3, "malformed input")                       \
    X(PF_EINVAL,      -4, "invalid argument")                      \
    X(PF_ERANGE,      -5, "value out of range")                    \
    X(PF_EUNSUPPORTED,-6, "unsupported feature")                   \
    X(PF_EAGAIN,      -7, "try again")                             \
    X(PF_ETIMEOUT,    -8, "timed out")                             \
    X(PF_EEMBREE,     -9, "ray-tracing kernel (Embree) error")     \
    X(PF_EMISMATCH,  -10, "version or fingerprint mismatch")       \
    X(PF_ESIZE,      -11, "image sizes do not fit")                \
    X(PF_EINTERRUPTED,-12, "interrupted")

typedef enum {
#define PF_STATUS_ENUM(name, value, text) name = value,
    PF_STATUS_LIST(PF_STATUS_ENUM)
#undef PF_STATUS_ENUM
} pf_status;

/* Human-readable text for a status code; never NULL. */
const char *pf_strerror(int status);

/* An error report from anything that reads outside input: "file:line: what".
 * Functions that take a pf_error_t * fill it when they fail (it may be NULL). */
typedef struct pf_error {
    char msg[1024];
} pf_error_t;

/* Formats "file:line: message" into err (line 0 omits the line). Returns status. */
int pf_error_set(pf_error_t *err, int status, const char *file, int line, const char *fmt, ...)
    __attribute__((format(printf, 5, 6)));

/* Programmer-error checks: PF_CHECK is always on, PF_DCHECK only in debug builds.
 * Never use either on bytes that came from a file or a socket. */
void pf_check_failed(const char *expr, const char *file, int line) __attribute__((noreturn));
#define PF_CHECK(expr) ((expr) ? (void)0 : pf_check_failed(#expr, __FILE__, __LINE__))
#ifdef NDEBUG
#define PF_DCHECK(expr) ((void)0)
#else
#define PF_DCHECK(expr) PF_CHECK(expr)
#endif

#endif
