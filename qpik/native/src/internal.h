/* A function that the C files of one library call from one another but that the library does not export (a direct
 * call, never resolved through the dynamic linker). */
#ifndef QPIK_INTERNAL_H
#define QPIK_INTERNAL_H

#define QPIK_INTERNAL __attribute__((visibility("hidden")))

#endif
