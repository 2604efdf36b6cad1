# Meshes (libas/src/mesh*.c, mesh_import_*.cpp): fixtures in tests/data, and
# the real scenes of ../shared/scenes (skipped when absent, failed under CI=true).
as_add_test(test_mesh_import SOURCES test_mesh_import.c LABELS mesh)
as_add_test(test_mesh_import_scenes SOURCES test_mesh_import.c ARGS scenes LABELS "mesh;scenes")
