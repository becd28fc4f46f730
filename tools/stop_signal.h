#pragma once
// The stop signal lives in service/daemon/stop_signal.h (one helper for the
// daemon and the tools). This forwarding header stays only until
// tools/simulate_tracker_command.cc, changed in another branch, includes that
// header directly; then delete it.
#include "service/daemon/stop_signal.h"
