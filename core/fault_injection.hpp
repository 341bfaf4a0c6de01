#pragma once
/// Test-only fault injection: the hard-kill tests make Scout kill itself with SIGKILL at named
/// points, the moments a power cut or an OOM kill may choose. SCOUT_FAULT_KILL_AT="POINT:N" kills
/// the process the N-th time it reaches POINT. Unset (always, outside those tests), a point costs
/// one load of a static.
///
/// Points: "batch" (a training step between backward and Adam's step), "file-write" (an atomic
/// write with half of the temporary file written: checkpoints, metrics, manifests, reports),
/// "validation" (between two validation batches), "output-commit" (an output folder replaced by
/// --overwrite, between moving the old one aside and the new one in).
namespace scout::core {

void fault_point(const char* point);

}  // namespace scout::core
