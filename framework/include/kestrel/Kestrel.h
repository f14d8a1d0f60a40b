#pragma once
// Everything a pass plugin needs.
#include "kestrel/Conventions.h"
#include "kestrel/Error.h"
#include "kestrel/Format.h"
#include "kestrel/FrameContext.h"
#include "kestrel/Image.h"
#include "kestrel/Log.h"
#include "kestrel/Math.h"
#include "kestrel/Parallel.h"
#include "kestrel/Params.h"
#include "kestrel/Pass.h"
#include "kestrel/Plugin.h"
#include "kestrel/Registry.h"
