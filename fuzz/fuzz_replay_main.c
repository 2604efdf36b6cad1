/* Replays fuzz corpora without libFuzzer: every regular file in the
 * directories (or the files) named on the command line goes through the
 * harness's LLVMFuzzerTestOneInput once, so ctest runs the corpus in every
 * build. A harness reports a bad input by aborting. */
#define _POSIX_C_SOURCE 200809L
#include <dirent.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static int replay_file(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        fprintf(stderr, "%s: cannot open\n", path);
        return 0;
    }
    uint8_t *buf = NULL;
    size_t size = 0, cap = 0;
    for (;;) {
        if (size == cap) {
            cap = cap ? 2 * cap : 4096;
            uint8_t *p = realloc(buf, cap);
            if (!p) {
                fprintf(stderr, "%s: out of memory\n", path);
                free(buf);
                fclose(f);
                return 0;
            }
            buf = p;
        }
        const size_t n = fread(buf + size, 1, cap - size, f);
        size += n;
        if (n == 0) break;
    }
    const int ok = !ferror(f);
    fclose(f);
    if (!ok) {
        fprintf(stderr, "%s: read error\n", path);
        free(buf);
        return 0;
    }
    /* An exact-size copy, as libFuzzer passes it. */
    uint8_t *exact = malloc(size ? size : 1);
    if (exact && size) memcpy(exact, buf, size);
    free(buf);
    if (!exact) return 0;
    LLVMFuzzerTestOneInput(exact, size);
    free(exact);
    return 1;
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        fprintf(stderr, "usage: %s CORPUS_DIR_OR_FILE...\n", argv[0]);
        return 1;
    }
    unsigned long count = 0;
    int errors = 0;
    for (int a = 1; a < argc; ++a) {
        struct stat st;
        if (stat(argv[a], &st) != 0) {
            fprintf(stderr, "%s: no such file or directory\n", argv[a]);
            ++errors;
            continue;
        }
        if (!S_ISDIR(st.st_mode)) {
            if (replay_file(argv[a])) ++count; else ++errors;
            continue;
        }
        DIR *d = opendir(argv[a]);
        if (!d) {
            fprintf(stderr, "%s: cannot open directory\n", argv[a]);
            ++errors;
            continue;
        }
        for (struct dirent *e; (e = readdir(d));) {
            if (e->d_name[0] == '.') continue;
            char path[4096];
            snprintf(path, sizeof path, "%s/%s", argv[a], e->d_name);
            if (stat(path, &st) != 0 || !S_ISREG(st.st_mode)) continue;
            if (replay_file(path)) ++count; else ++errors;
        }
        closedir(d);
    }
    printf("replayed %lu inputs\n", count);
    /* An empty corpus means a wrong path, not a pass. */
    return errors || count == 0 ? 1 : 0;
}
