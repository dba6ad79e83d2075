#pragma once
// conesim's SDK: everything a plug-in includes (docs/sdk.md).

#include "conesim/sdk/config.hpp"
#include "conesim/sdk/geometry.hpp"
#include "conesim/sdk/interfaces.hpp"
#include "conesim/sdk/plugin.hpp"
#include "conesim/sdk/types.hpp"
#include "conesim/sdk/version.hpp"
