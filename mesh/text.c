/* text.c: the parts of the OBJ and MTL statement reading (text.h) that are
 * not on the per-byte path: error and warning reports, the rest of a line
 * as a name, and the read loop. Called by obj.c and mtl.c on the one thread
 * that builds the scene; owns nothing beyond a call. */
#include "mesh/text.h"

#include <errno.h>
#include <string.h>

#include "base/log.h"

int pf_text_bad_number(pf_error_t *err, const char *path, int line, const char *p)
{
    p = pf_text_skip_ws(p);
    return pf_error_set(err, PF_EPARSE, path, line, "malformed number '%.*s'", pf_text_show(p), p);
}

const char *pf_text_rest(const char *p, size_t *n)
{
    p = pf_text_skip_ws(p);
    size_t len = strcspn(p, "\n#");
    while (len > 0 && pf_text_is_ws(p[len - 1]))
        len--;
    *n = len;
    return p;
}

void pf_text_warn_keyword(pf_text_warned_t *w, const char *path, int line, const char *kw, int len)
{
    if (len > (int)sizeof w->kw[0] - 1)
        len = (int)sizeof w->kw[0] - 1;
    for (int i = 0; i < w->n; i++)
        if ((int)strlen(w->kw[i]) == len && strncmp(w->kw[i], kw, (size_t)len) == 0)
            return;
    if (w->n < w->max && w->n < PF_TEXT_WARNED_MAX) {
        snprintf(w->kw[w->n], sizeof w->kw[0], "%.*s", len, kw);
        w->n++;
    }
    pf_warn("%s:%d: ignoring unsupported statement '%.*s' (warned once per keyword)", path, line, len, kw);
}

int pf_text_read_statements(FILE *f, const char *path, int *line, pf_error_t *err, pf_text_statement_fn fn,
                            void *arg)
{
    int rc = PF_OK;
    char *buf = NULL;
    size_t cap = 0;
    while (rc == PF_OK && getline(&buf, &cap, f) >= 0) {
        (*line)++;
        const char *p = pf_text_skip_ws(buf);
        if (pf_text_is_eol(*p))
            continue;
        int kwlen = pf_text_token_len(p);
        rc = fn(arg, p, kwlen, p + kwlen);
    }
    /* getline also returns -1 when it cannot grow its buffer (a line too
     * long for memory, e.g. a device read as a model): only the end of the
     * file ends the file, anything else is an error, not a truncation. */
    if (rc == PF_OK && (ferror(f) || !feof(f)))
        rc = pf_error_set(err, errno == ENOMEM ? PF_ENOMEM : PF_EIO, path, *line + 1, "read error: %s",
                          errno == ENOMEM ? "a line too long for memory" : strerror(errno));
    free(buf);
    return rc;
}
