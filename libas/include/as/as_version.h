/* The version of libas these headers belong to (CMake reads it from here). */
#ifndef AS_AS_VERSION_H
#define AS_AS_VERSION_H

#define AS_VERSION_MAJOR 0
#define AS_VERSION_MINOR 1
#define AS_VERSION_PATCH 0
#define AS_VERSION_NUMBER (AS_VERSION_MAJOR * 10000 + AS_VERSION_MINOR * 100 + AS_VERSION_PATCH)
#define AS_VERSION_STRING "0.1.0"

#endif
