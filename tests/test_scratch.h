/* A scratch directory per test program, for the tests of the file writers:
 * paths in it, a count of a writer's leftovers (NAME.tmp.XXXXXX), and its
 * removal. */
#ifndef AS_TEST_SCRATCH_H
#define AS_TEST_SCRATCH_H

#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char tmp_dir[64];

/* Makes /tmp/PREFIX_XXXXXX; 0 when it could not. */
static inline int tmp_dir_make(const char *prefix)
{
    snprintf(tmp_dir, sizeof tmp_dir, "/tmp/%s_XXXXXX", prefix);
    if (mkdtemp(tmp_dir)) return 1;
    perror("mkdtemp");
    return 0;
}

/* FILE in the scratch directory; four results may be in use at once. */
static inline const char *tmp_path(const char *file)
{
    static char buf[4][512];
    static int next;
    char *p = buf[next++ % 4];
    snprintf(p, sizeof buf[0], "%s/%s", tmp_dir, file);
    return p;
}

/* Names in the scratch directory holding ".tmp.": a writer's leftovers
 * (-1 when the directory cannot be read). */
static inline int temp_leftovers(void)
{
    DIR *d = opendir(tmp_dir);
    if (!d) return -1;
    int n = 0;
    for (struct dirent *e; (e = readdir(d));) {
        if (strstr(e->d_name, ".tmp.")) {
            fprintf(stderr, "  left behind: %s\n", e->d_name);
            ++n;
        }
    }
    closedir(d);
    return n;
}

static inline void remove_tmp_dir(void)
{
    DIR *d = opendir(tmp_dir);
    for (struct dirent *e; d && (e = readdir(d));)
        if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..")) remove(tmp_path(e->d_name));
    if (d) closedir(d);
    rmdir(tmp_dir);
}

#endif
