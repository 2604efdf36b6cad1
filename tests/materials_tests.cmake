# Whitted materials from an OBJ's material library (libas/src/materials_mtl.c).
as_add_test(test_materials SOURCES test_materials.c LABELS mesh)
