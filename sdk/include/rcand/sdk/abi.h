/* rcand plugin ABI: the one C entry point every plugin library exports.
 *
 * The kernel resolves the symbol RCAND_ENTRY_SYMBOL ("rcand_plugin_entry_v<MAJOR>") and checks the
 * descriptor it returns before calling anything else: magic, struct_size (not larger than the kernel's,
 * not smaller than the 1.0 layout), abi_major equal, abi_minor not newer, id and version equal to the
 * manifest. Putting the major in the symbol name means a library built for another major is not even
 * found under the kernel's name; the kernel then probes other majors only to explain the failure. */
#ifndef RCAND_SDK_ABI_H
#define RCAND_SDK_ABI_H

#include <stdint.h>

#define RCAND_ABI_MAJOR 1
#define RCAND_ABI_MINOR 3                  /* what each minor added: rcand/sdk/context.hpp */
#define RCAND_DESCRIPTOR_MAGIC 0x52434e44u /* "RCND" */

#define RCAND_STRINGIFY_(x) #x
#define RCAND_STRINGIFY(x) RCAND_STRINGIFY_(x)
#define RCAND_ENTRY_NAME_(major) rcand_plugin_entry_v##major
#define RCAND_ENTRY_NAME(major) RCAND_ENTRY_NAME_(major)
/* The exported function's name for this SDK's ABI major, as an identifier and as a string. */
#define RCAND_ENTRY_FUNCTION RCAND_ENTRY_NAME(RCAND_ABI_MAJOR)
#define RCAND_ENTRY_SYMBOL "rcand_plugin_entry_v" RCAND_STRINGIFY(RCAND_ABI_MAJOR)

#if defined(__GNUC__)
#define RCAND_EXPORT __attribute__((visibility("default")))
#else
#define RCAND_EXPORT
#endif

#ifdef __cplusplus
extern "C" {
#endif

/* Opaque in C; it is rcand::sdk::Registrar in C++. */
struct rcand_registrar;

/* Size-prefixed: fields are only ever appended, and struct_size tells the kernel which ones exist. */
typedef struct rcand_plugin_descriptor {
  uint32_t struct_size;   /* sizeof(rcand_plugin_descriptor) as the plugin was built */
  uint32_t magic;         /* RCAND_DESCRIPTOR_MAGIC */
  uint16_t abi_major;     /* must equal the kernel's */
  uint16_t abi_minor;     /* must not be newer than the kernel's */
  const char* plugin_id;  /* reverse-domain id, equal to the manifest's "id" */
  const char* version;    /* equal to the manifest's "version" */
  const char* build_info; /* compiler and build date, shown by rcand --check-plugins */
  /* Called exactly once, before any other call into the plugin, on a kernel thread of its own while the
   * main thread waits (at most runtime.plugin_start_timeout_ms; one that overruns is registration-failed).
   * It registers what the manifest "provides" lists, no more and no less. May throw: the kernel's
   * guarded trampoline catches it and records the plugin as registration-failed. */
  void (*register_plugin)(struct rcand_registrar* registrar);
} rcand_plugin_descriptor;

/* The entry point's type. It must not throw and must not allocate: it returns a static descriptor. */
typedef const rcand_plugin_descriptor* (*rcand_plugin_entry_fn)(void);

#ifdef __cplusplus
}
#endif

#endif /* RCAND_SDK_ABI_H */
