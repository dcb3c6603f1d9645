// Interface types shared across the plugin boundary keep default visibility, so RTTI (dynamic_cast to a
// driver interface) works between the kernel and plugins built with -fvisibility=hidden.
#pragma once
#include "rcand/sdk/abi.h"
#define RCAND_INTERFACE RCAND_EXPORT
