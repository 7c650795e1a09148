/* progress.c: the terminal progress bar; see progress.h. */
#include "coordinator/progress.h"

#include <stdio.h>
#include <unistd.h>

#include "base/log.h"

void pf_progress_begin(pf_progress_t *p, const char *label, int enabled)
{
    p->label = label;
    p->enabled = enabled && isatty(STDERR_FILENO) && pf_log_get_level() <= PF_LOG_INFO;
    p->start = p->last = pf_now();
    p->drawn = 0;
    if (p->enabled) {
        fprintf(stderr, "\r%-8s ...", label);
        fflush(stderr);
        p->drawn = 1;
    }
}

void pf_progress_update(pf_progress_t *p, int done, int total) { pf_progress_update_note(p, done, total, NULL); }

void pf_progress_update_note(pf_progress_t *p, int done, int total, const char *note)
{
    if (!p->enabled || total <= 0)
        return;
    double now = pf_now();
    if (done < total && now - p->last < 0.1)
        return;
    p->last = now;
    const int width = 30;
    int fill = (int)((double)done / total * width);
    char bar[64];
    for (int i = 0; i < width; i++)
        bar[i] = i < fill ? '#' : '.';
    bar[width] = 0;
    double el = now - p->start;
    double rate = el > 0 ? done / el : 0;
    double eta = rate > 0 ? (total - done) / rate : 0;
    fprintf(stderr, "\r\033[K%-8s [%s] %d/%d tiles  %.1f tiles/s  ETA %.0f s%s%s", p->label, bar, done, total, rate,
            eta, note ? "  " : "", note ? note : "");
    fflush(stderr);
    p->drawn = 1;
}

void pf_progress_tiles(void *user, int done, int total) { pf_progress_update(user, done, total); }

void pf_progress_end(pf_progress_t *p)
{
    if (p->enabled && p->drawn) {
        fprintf(stderr, "\r\033[K");
        fflush(stderr);
    }
}
