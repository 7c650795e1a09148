/* sync.h: private to image/. What the image writers (image.c, exr.c) share
 * to make a finished file survive a crash. */
#ifndef PF_IMAGE_SYNC_H
#define PF_IMAGE_SYNC_H

/* fsyncs the directory that holds path, so a rename into it survives a
 * crash. 0, or an errno; EINVAL (a file system that cannot sync a
 * directory) counts as done. Defined in image.c. */
int pf_image_sync_dir(const char *path);

#endif
