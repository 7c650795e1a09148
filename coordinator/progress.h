/* progress.h: a one-line progress bar on a terminal (stderr), silent when
 * stderr is not a terminal or when disabled. Updated from one thread. */
#ifndef PF_PROGRESS_H
#define PF_PROGRESS_H

typedef struct pf_progress {
    const char *label;
    int enabled;
    double start, last;
    int drawn;
} pf_progress_t;

void pf_progress_begin(pf_progress_t *p, const char *label, int enabled);
/* Draws done/total with rate and ETA (at most ~10 times a second). */
void pf_progress_update(pf_progress_t *p, int done, int total);
/* The same with extra text after the ETA (e.g. workers alive, transfers). */
void pf_progress_update_note(pf_progress_t *p, int done, int total, const char *note);
/* Adapter for pf_progress_fn (user = pf_progress_t *). */
void pf_progress_tiles(void *user, int done, int total);
void pf_progress_end(pf_progress_t *p);

#endif
