/* Whitted materials from an OBJ's material library: what each material
 * becomes (the rule in as.h), the rays each one makes in a bounce, and the
 * files and statements that are refused, each with a message that names
 * the file and line. Fixture: tests/data/cli/whitted_materials.obj (a
 * diffuse floor, a mirror, a glass pane of Ni 1.33, two triangles each). */
#include "as/as.h"
#include "test_util.h"

#include <math.h>
#include <sys/stat.h>

static char fixture[1024];
static char tmpdir[256];

static void write_text(const char *name, const char *text)
{
    char path[512];
    snprintf(path, sizeof path, "%s/%s", tmpdir, name);
    FILE *f = fopen(path, "w");
    if (!f) { perror(path); exit(1); }
    fputs(text, f);
    fclose(f);
}

/* The OBJ of a single triangle under `usemtl` names, with `header` first. */
static const char *tmp_obj(const char *name, const char *header)
{
    static char path[512];
    char text[1024];
    snprintf(text, sizeof text, "%sv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n", header);
    write_text(name, text);
    snprintf(path, sizeof path, "%s/%s", tmpdir, name);
    return path;
}

/* Reads the materials of `obj`; returns the error, with the message in `msg`. */
static as_error_t read_materials(const char *obj, as_material_t **mats, uint32_t *n)
{
    as_mesh_t *mesh = as_mesh_import(obj);
    if (!mesh) return as_get_error();
    const as_error_t e = as_materials_read_obj(obj, mesh, mats, n);
    as_mesh_release(mesh);
    return e;
}

static void fixture_materials_follow_the_mtl_rule(void)
{
    as_material_t *m = NULL;
    uint32_t n = 0;
    CHECK_EQ_INT(read_materials(fixture, &m, &n), AS_OK);
    CHECK_EQ_INT(n, 6);
    if (n != 6) { free(m); return; }
    /* Triangles in file order, two per quad. */
    for (int t = 0; t < 2; ++t) CHECK_EQ_INT(m[t].kind, AS_MATERIAL_OPAQUE);     /* floor: Ks 0.2, illum 2 */
    for (int t = 2; t < 4; ++t) CHECK_EQ_INT(m[t].kind, AS_MATERIAL_MIRROR);     /* illum 3 */
    for (int t = 4; t < 6; ++t) {
        CHECK_EQ_INT(m[t].kind, AS_MATERIAL_GLASS);                              /* d 0.1 */
        CHECK(fabsf(m[t].ior - 1.33f) < 1e-6f);
    }
    free(m);
}

/* One ray straight at a point, and the bounce of its hit. */
typedef struct bounce_result {
    size_t next, shadow;
    as_ray_t next_rays[4];
} bounce_result;

static bounce_result bounce(const as_structure_t *s, const as_material_t *m, uint32_t n, const float org[3],
                            const float dir[3])
{
    bounce_result out;
    memset(&out, 0, sizeof out);
    as_ray_t ray = {{org[0], org[1], org[2]}, 0.0f, {dir[0], dir[1], dir[2]}, INFINITY};
    as_hit_t hit;
    as_trace_args_t ta;
    as_trace_args_default(&ta);
    ta.device = AS_DEVICE_CPU;
    CHECK_EQ_INT(as_trace(s, &ray, 1, &hit, &ta, NULL), AS_OK);
    CHECK(hit.prim != AS_NO_HIT);
    as_whitted_args_t wa;
    as_whitted_args_default(&wa);
    const float light[3] = {0, 5, 5};
    wa.lights = light;
    wa.light_count = 1;
    wa.materials = m;
    wa.material_count = n;
    as_ray_t *nx = NULL, *sh = NULL;
    CHECK_EQ_INT(as_rays_whitted_bounce(s, &ray, &hit, 1, &wa, &nx, &out.next, &sh, &out.shadow), AS_OK);
    for (size_t i = 0; i < out.next && i < 4; ++i) out.next_rays[i] = nx[i];
    free(nx);
    free(sh);
    return out;
}

static void each_material_makes_the_rays_it_implies(void)
{
    as_mesh_t *mesh = as_mesh_import(fixture);
    CHECK(mesh != NULL);
    if (!mesh) return;
    as_structure_t *s = as_structure_build(mesh, NULL);
    as_material_t *m = NULL;
    uint32_t n = 0;
    CHECK_EQ_INT(as_materials_read_obj(fixture, mesh, &m, &n), AS_OK);
    as_mesh_release(mesh);
    CHECK(s != NULL);
    if (!s || !m) { as_structure_release(s); free(m); return; }
    const float down[3] = {0, -1, 0}, back[3] = {0, 0, -1};
    const float over_floor[3] = {0, 2, 2}, at_mirror[3] = {-1.5f, 1, 5}, at_glass[3] = {1.5f, 1, 5};

    bounce_result r = bounce(s, m, n, over_floor, down);
    CHECK_EQ_U64(r.shadow, 1); /* every hit: one shadow ray per light */
    CHECK_EQ_U64(r.next, 0);   /* diffuse floor: no reflection */

    r = bounce(s, m, n, at_mirror, back);
    CHECK_EQ_U64(r.shadow, 1);
    CHECK_EQ_U64(r.next, 1);   /* mirror: the reflection, straight back */
    CHECK(r.next_rays[0].dir[2] > 0.99f);

    r = bounce(s, m, n, at_glass, back);
    CHECK_EQ_U64(r.shadow, 1);
    CHECK_EQ_U64(r.next, 2);   /* glass: reflection and refraction */
    CHECK(r.next_rays[0].dir[2] > 0.99f && r.next_rays[1].dir[2] < -0.99f);

    /* The material's Ni bends the refraction, not the default ior 1.5:
     * sin t = sin i / 1.33. */
    const float slant[3] = {0.5f, 0, -1};
    const float slant_org[3] = {1.5f - 0.5f * 5, 1, 5};
    r = bounce(s, m, n, slant_org, slant);
    CHECK_EQ_U64(r.next, 2);
    if (r.next == 2) {
        const float *d = r.next_rays[1].dir;
        const double sin_t = d[0] / sqrt((double)d[0] * d[0] + (double)d[1] * d[1] + (double)d[2] * d[2]);
        const double want = (0.5 / sqrt(1.25)) / 1.33;
        if (fabs(sin_t - want) > 1e-5) fprintf(stderr, "refraction: sin t %.6f, want %.6f\n", sin_t, want);
        CHECK(fabs(sin_t - want) <= 1e-5);
    }

    as_whitted_args_t wa;
    as_whitted_args_default(&wa);
    wa.materials = m;
    wa.material_count = n;
    CHECK_EQ_INT(as_whitted_material(&wa, 3), AS_MATERIAL_MIRROR);
    CHECK_EQ_INT(as_whitted_material(&wa, 4), AS_MATERIAL_GLASS);

    /* A material array of another size is refused. */
    wa.material_count = n - 1;
    as_ray_t ray = {{0, 2, 2}, 0, {0, -1, 0}, INFINITY};
    as_hit_t hit = {1.0f, 0, 0.2f, 0.2f};
    as_ray_t *nx = NULL, *sh = NULL;
    size_t nn = 0, ns = 0;
    CHECK_EQ_INT(as_rays_whitted_bounce(s, &ray, &hit, 1, &wa, &nx, &nn, &sh, &ns), AS_ERROR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(as_get_error_message(), "5 materials for a structure of 6 triangles");
    free(m);
    as_structure_release(s);
}

static void rule_variants(void)
{
    /* d, Tr, illum 4/6/7/9 make glass; illum 3/5 or Ks >= 0.8 a mirror. */
    static const struct { const char *mtl; int kind; float ior; } cases[] = {
        {"newmtl a\nKs 0.5 0.5 0.5\n", AS_MATERIAL_OPAQUE, 0},
        {"newmtl a\nKs 0.9\n", AS_MATERIAL_MIRROR, 0},
        {"newmtl a\nKs 0.9 0.9 0.7\n", AS_MATERIAL_OPAQUE, 0},
        {"newmtl a\nillum 5\n", AS_MATERIAL_MIRROR, 0},
        {"newmtl a\nTr 0.5\n", AS_MATERIAL_GLASS, 0},
        {"newmtl a\nillum 6\nNi 2.4\n", AS_MATERIAL_GLASS, 2.4f},
        {"newmtl a\nillum 9\n", AS_MATERIAL_GLASS, 0},
        {"newmtl a\nd 1\nillum 2\n", AS_MATERIAL_OPAQUE, 0},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        write_text("v.mtl", cases[i].mtl);
        const char *obj = tmp_obj("v.obj", "mtllib v.mtl\n");
        as_material_t *m = NULL;
        uint32_t n = 0;
        CHECK_EQ_INT(read_materials(obj, &m, &n), AS_OK);
        if (m && n == 1) {
            if (m[0].kind != (uint32_t)cases[i].kind) fprintf(stderr, "case %zu: %s", i, cases[i].mtl);
            CHECK_EQ_INT(m[0].kind, cases[i].kind);
            CHECK(fabsf(m[0].ior - cases[i].ior) < 1e-6f);
        }
        free(m);
    }
}

/* Reads `obj` expecting `code` and a message with each of the needles. */
static void expect_refused(const char *obj, as_error_t code, const char *needle1, const char *needle2)
{
    as_material_t *m = (as_material_t *)1;
    uint32_t n = 7;
    CHECK_EQ_INT(read_materials(obj, &m, &n), code);
    CHECK_STR_CONTAINS(as_get_error_message(), needle1);
    if (needle2) CHECK_STR_CONTAINS(as_get_error_message(), needle2);
    CHECK(m == NULL && n == 0);
}

static void bad_libraries_are_refused_naming_file_and_line(void)
{
    char want[512];
    /* A library that is not there: the library's path and the OBJ's line. */
    const char *obj = tmp_obj("missing.obj", "# a comment\nmtllib none.mtl\n");
    snprintf(want, sizeof want, "%s/none.mtl: no such file", tmpdir);
    expect_refused(obj, AS_ERROR_FILE_NOT_FOUND, want, "mtllib on line 2 of");

    /* usemtl of a material no library defines: the OBJ and its line. */
    write_text("other.mtl", "newmtl b\nKs 1 1 1\n");
    obj = tmp_obj("unknown.obj", "mtllib other.mtl\n");
    snprintf(want, sizeof want, "%s: line 5: usemtl 'a': no material of that name", obj);
    expect_refused(obj, AS_ERROR_PARSE, want, NULL);

    /* A malformed statement: the library and its line. */
    write_text("bad.mtl", "newmtl a\n\nKs 1 x 1\n");
    obj = tmp_obj("badks.obj", "mtllib bad.mtl\n");
    snprintf(want, sizeof want, "%s/bad.mtl: line 3: Ks needs 1 or 3 numbers", tmpdir);
    expect_refused(obj, AS_ERROR_PARSE, want, NULL);
    write_text("bad2.mtl", "Ni 1.5\nnewmtl a\n");
    obj = tmp_obj("early.obj", "mtllib bad2.mtl\n");
    expect_refused(obj, AS_ERROR_PARSE, "bad2.mtl: line 1: Ni before any newmtl", NULL);

    /* No library at all. */
    obj = tmp_obj("nolib.obj", "");
    expect_refused(obj, AS_ERROR_PARSE, "line 4: usemtl 'a' but the file names no material library", NULL);

    /* Only beside the OBJ: no absolute paths, no "..". */
    obj = tmp_obj("abs.obj", "mtllib /etc/passwd\n");
    expect_refused(obj, AS_ERROR_IO, "line 1: mtllib '/etc/passwd' is an absolute path", NULL);
    obj = tmp_obj("up.obj", "mtllib ../x.mtl\n");
    expect_refused(obj, AS_ERROR_IO, "line 1: mtllib '../x.mtl' leaves the OBJ's directory", NULL);

    /* Not a regular file: a FIFO is refused at once (no writer is waited
     * for), and so is a directory. */
    char fifo[512];
    snprintf(fifo, sizeof fifo, "%s/pipe.mtl", tmpdir);
    if (mkfifo(fifo, 0600) == 0) {
        obj = tmp_obj("fifo.obj", "mtllib pipe.mtl\n");
        expect_refused(obj, AS_ERROR_IO, "pipe.mtl: not a regular file (a FIFO): refused", NULL);
    } else {
        fprintf(stderr, "note: mkfifo failed, FIFO case not checked\n");
    }
    char dir[512];
    snprintf(dir, sizeof dir, "%s/dir.mtl", tmpdir);
    mkdir(dir, 0700);
    obj = tmp_obj("dir.obj", "mtllib dir.mtl\n");
    expect_refused(obj, AS_ERROR_IO, "dir.mtl: not a regular file (a directory): refused", NULL);
}

static void mesh_of_another_file_is_refused(void)
{
    /* The fixture's mesh (three materials) against a one-material OBJ. */
    as_mesh_t *mesh = as_mesh_import(fixture);
    write_text("one.mtl", "newmtl a\n");
    const char *obj = tmp_obj("one.obj", "mtllib one.mtl\n");
    as_material_t *m = NULL;
    uint32_t n = 0;
    CHECK_EQ_INT(as_materials_read_obj(obj, mesh, &m, &n), AS_ERROR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(as_get_error_message(), "the mesh was not imported from this file");
    CHECK(m == NULL);
    as_mesh_release(mesh);
}

int main(void)
{
    snprintf(fixture, sizeof fixture, "%s/tests/data/cli/whitted_materials.obj", AS_SOURCE_DIR);
    snprintf(tmpdir, sizeof tmpdir, "%s/as-materials.XXXXXX", getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp");
    if (!mkdtemp(tmpdir)) { perror("mkdtemp"); return 1; }
    RUN_TEST(fixture_materials_follow_the_mtl_rule);
    RUN_TEST(each_material_makes_the_rays_it_implies);
    RUN_TEST(rule_variants);
    RUN_TEST(bad_libraries_are_refused_naming_file_and_line);
    RUN_TEST(mesh_of_another_file_is_refused);
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    if (system(cmd) != 0) fprintf(stderr, "note: could not remove %s\n", tmpdir);
    TEST_EXIT();
}
