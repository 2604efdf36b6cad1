/* No data lost: a write over an existing file either replaces it whole or
 * leaves it byte-identical, reports the error with the file's name, and
 * leaves no temporary file behind (formats/atomic_file.h). Each way a write
 * can fail is produced for real where the system allows it (a file-size
 * limit stands in for a full disk) and by fault injection where it does not:
 * the tests run as root, where permission bits cannot make a write, an fsync
 * or a rename fail. */
#include "atomic_file.h"
#include "as_internal.h"
#include "test_util.h"
#include "test_scratch.h"

#include <dirent.h>
#include <errno.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>

/* A flat strip of 2 * quads triangles: a structure whose file grows with
 * `quads` (48 bytes of TRI4 per triangle, plus nodes). */
static as_structure_t *strip_structure(uint32_t quads)
{
    float *pos = malloc(sizeof(float) * 6 * (quads + 1));
    uint32_t *idx = malloc(sizeof(uint32_t) * 6 * quads);
    for (uint32_t i = 0; i <= quads; ++i) {
        const float x = (float)i;
        const float v[6] = {x, 0.0f, 0.0f, x, 1.0f, 0.0f};
        memcpy(pos + 6 * i, v, sizeof v);
    }
    for (uint32_t i = 0; i < quads; ++i) {
        const uint32_t a = 2 * i, b = 2 * i + 1, c = 2 * i + 2, d = 2 * i + 3;
        const uint32_t t[6] = {a, c, b, b, c, d};
        memcpy(idx + 6 * i, t, sizeof t);
    }
    as_mesh_t *mesh = as_mesh_create(2 * (quads + 1), pos, 2 * quads, idx);
    free(pos);
    free(idx);
    if (!mesh) return NULL;
    as_structure_t *s = as_structure_build(mesh, NULL);
    as_mesh_release(mesh);
    return s;
}

/* The previous file: a small structure written normally. Returns its bytes. */
static unsigned char *write_previous(const char *path, size_t *size)
{
    as_structure_t *s = strip_structure(1);
    if (!s || test_save_reproducible(s, path) != AS_OK) {
        fprintf(stderr, "cannot write the previous file %s: %s\n", path, as_get_error_message());
        exit(1);
    }
    as_structure_release(s);
    unsigned char *data = NULL;
    if (!test_read_file(path, &data, size)) exit(1);
    return data;
}

static int file_holds(const char *path, const unsigned char *data, size_t size)
{
    unsigned char *now = NULL;
    size_t n = 0;
    const int same = test_read_file(path, &now, &n) && n == size && memcmp(now, data, size) == 0;
    free(now);
    return same;
}

/* The baseline the failure tests are measured against: a successful save
 * over an existing file replaces it and leaves nothing beside it. */
static void save_over_existing_file_replaces_it_whole(void)
{
    const char *path = tmp_path("replace.asf");
    size_t old_size;
    unsigned char *old = write_previous(path, &old_size);
    as_structure_t *s = strip_structure(200);
    CHECK(s != NULL);
    CHECK_EQ_INT(test_save_reproducible(s, path), AS_OK);
    CHECK(!file_holds(path, old, old_size));
    as_structure_t *back = as_structure_load(path, NULL);
    CHECK(back != NULL);
    CHECK_EQ_INT(as_structure_validate(back), AS_OK);
    as_structure_release(back);
    CHECK_EQ_INT(temp_leftovers(), 0);
    as_structure_release(s);
    free(old);
    unlink(path);
}

/* A full disk, for real: the child may write at most 4 KB per file
 * (RLIMIT_FSIZE), so write(2) fails with EFBIG partway through the
 * structure's 10 KB, as it fails with ENOSPC when a disk fills. SIGXFSZ is
 * ignored, so the failure reaches the writer instead of killing the process.
 * The child reports the error code, and whether the message names the file,
 * through its exit status. */
static void full_disk_leaves_previous_file_and_no_temporary(void)
{
    const char *path = tmp_path("full.asf");
    size_t old_size;
    unsigned char *old = write_previous(path, &old_size);
    CHECK(old_size < 4096);
    as_structure_t *s = strip_structure(200);
    CHECK(s != NULL);

    const pid_t pid = fork();
    if (pid == 0) {
        signal(SIGXFSZ, SIG_IGN);
        const struct rlimit limit = {4096, 4096};
        if (setrlimit(RLIMIT_FSIZE, &limit) != 0) _exit(100);
        const as_error_t err = test_save_reproducible(s, path);
        const char *msg = as_get_error_message();
        fprintf(stderr, "  child: %s\n", msg);
        const int named = strstr(msg, path) != NULL && strstr(msg, strerror(EFBIG)) != NULL;
        _exit(err == AS_ERROR_IO && named ? 0 : err == AS_OK ? 101 : 102);
    }
    int status = 0;
    CHECK(pid > 0 && waitpid(pid, &status, 0) == pid);
    CHECK(WIFEXITED(status));
    /* 0: AS_ERROR_IO with the path and "File too large"; 101: the save
     * claimed success; 102: another error or an unnamed one. */
    CHECK_EQ_INT(WEXITSTATUS(status), 0);
    CHECK(file_holds(path, old, old_size));
    CHECK_EQ_INT(temp_leftovers(), 0);
    as_structure_release(s);
    free(old);
    unlink(path);
}

/* Every stage of the write failing in turn, through the test-only fault
 * hook: the save reports AS_ERROR_IO naming the file and the system error,
 * the previous file is byte-identical, and no temporary file is left. */
static void failed_create_write_sync_or_rename_leaves_previous_file(void)
{
    static const struct {
        as_atomic_fault_t stage;
        int error_number;
        const char *what; /* in the message */
    } faults[] = {
        {AS_ATOMIC_FAULT_CREATE, EMFILE, "cannot create temporary file"},
        {AS_ATOMIC_FAULT_WRITE, ENOSPC, "cannot write"},
        {AS_ATOMIC_FAULT_WRITE, EIO, "cannot write"},
        {AS_ATOMIC_FAULT_SYNC, EIO, "cannot sync"},
        {AS_ATOMIC_FAULT_RENAME, EXDEV, "cannot rename"},
    };
    const char *path = tmp_path("fault.asf");
    size_t old_size;
    unsigned char *old = write_previous(path, &old_size);
    as_structure_t *s = strip_structure(200);
    CHECK(s != NULL);
    for (size_t i = 0; i < sizeof faults / sizeof faults[0]; ++i) {
        as_atomic_file_inject_fault(faults[i].stage, faults[i].error_number);
        as_clear_error();
        const as_error_t err = test_save_reproducible(s, path);
        fprintf(stderr, "  %s: %s\n", faults[i].what, as_get_error_message());
        CHECK_EQ_INT(err, AS_ERROR_IO);
        CHECK_EQ_INT(as_get_error(), AS_ERROR_IO);
        CHECK_STR_CONTAINS(as_get_error_message(), path);
        CHECK_STR_CONTAINS(as_get_error_message(), faults[i].what);
        CHECK_STR_CONTAINS(as_get_error_message(), strerror(faults[i].error_number));
        CHECK(file_holds(path, old, old_size));
        CHECK_EQ_INT(temp_leftovers(), 0);
    }
    /* The fault fired once: the next save goes through. */
    CHECK_EQ_INT(test_save_reproducible(s, path), AS_OK);
    CHECK(!file_holds(path, old, old_size));
    CHECK_EQ_INT(temp_leftovers(), 0);
    as_structure_release(s);
    free(old);
    unlink(path);
}

/* Ray and hit files take the same path. */
static void failed_write_of_a_ray_file_leaves_previous_file(void)
{
    const char *path = tmp_path("fault.rays");
    as_ray_t rays[64];
    for (int i = 0; i < 64; ++i) rays[i] = (as_ray_t){{(float)i, 0.5f, 1.0f}, 0.0f, {0.0f, 0.0f, -1.0f}, 1e30f};
    CHECK_EQ_INT(as_rays_write(path, rays, 2), AS_OK);
    size_t old_size = 0;
    unsigned char *old = NULL;
    CHECK(test_read_file(path, &old, &old_size));
    as_atomic_file_inject_fault(AS_ATOMIC_FAULT_WRITE, ENOSPC);
    CHECK_EQ_INT(as_rays_write(path, rays, 64), AS_ERROR_IO);
    CHECK_STR_CONTAINS(as_get_error_message(), path);
    CHECK(file_holds(path, old, old_size));
    CHECK_EQ_INT(temp_leftovers(), 0);
    free(old);
    unlink(path);
}

int main(void)
{
    if (!tmp_dir_make("as_atomic_write")) return 1;
    RUN_TEST(save_over_existing_file_replaces_it_whole);
    RUN_TEST(full_disk_leaves_previous_file_and_no_temporary);
    RUN_TEST(failed_create_write_sync_or_rename_leaves_previous_file);
    RUN_TEST(failed_write_of_a_ray_file_leaves_previous_file);
    rmdir(tmp_dir);
    TEST_EXIT();
}
