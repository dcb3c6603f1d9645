// Forwarding header: pose_source.hpp is one of the SDK's domain interfaces, now in rcand/sdk/interfaces/ (the core a
// plugin must read stays here). Kept for sources written against ABI 1; ABI 2 drops it (sdk/README.md).
#pragma once

#include "rcand/sdk/interfaces/pose_source.hpp"
