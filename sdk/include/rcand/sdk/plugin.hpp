// The one header a plugin includes, and the one registration macro:
//
//   static void register_gripper(rcand::sdk::Registrar& r) { r.add_capability(...); r.add_driver(...); }
//   RCAND_PLUGIN("com.acme.gripper", "1.0.0", register_gripper)
//
// The id and version must equal the plugin's manifest. Exactly one RCAND_PLUGIN per library.
#pragma once

#include "rcand/sdk/abi.h"
#include "rcand/sdk/capability.hpp"
#include "rcand/sdk/context.hpp"
#include "rcand/sdk/driver.hpp"
#include "rcand/sdk/registrar.hpp"

#ifndef RCAND_PLUGIN_BUILD_INFO
#define RCAND_PLUGIN_BUILD_INFO "gcc " __VERSION__
#endif

#define RCAND_PLUGIN(ID, VERSION, REGISTER_FN)                                                           \
  extern "C" RCAND_EXPORT const rcand_plugin_descriptor* RCAND_ENTRY_FUNCTION(void) {                    \
    static const rcand_plugin_descriptor descriptor{                                                      \
        sizeof(rcand_plugin_descriptor), RCAND_DESCRIPTOR_MAGIC, RCAND_ABI_MAJOR, RCAND_ABI_MINOR, ID,    \
        VERSION, RCAND_PLUGIN_BUILD_INFO,                                                                 \
        [](rcand_registrar* registrar) { REGISTER_FN(*reinterpret_cast<rcand::sdk::Registrar*>(registrar)); }}; \
    return &descriptor;                                                                                   \
  }
