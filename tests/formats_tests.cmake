# The .asf container and the ray/hit files (formats/).
as_add_test(test_container SOURCES test_container.c LABELS formats)
as_add_test(test_records SOURCES test_records.c LABELS formats)
