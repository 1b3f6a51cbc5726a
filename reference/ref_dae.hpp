// What ref-dae (reference/ref_dae.cpp) takes from a Model besides its SceneSystem, exposed for
// its tests: the motion of a kinematic end of a rigid constraint.
#pragma once

#include "core/model.hpp"
#include "reference/dae_system.hpp"

namespace pbdbench::ref_dae {

// Position (m), velocity (m/s) and acceleration (m/s^2) of attachment `attachment`'s target at
// time t. Velocity and acceleration are right limits: at the start of an Oscillate or Circle
// motion (where motion_velocity gives the left limit, 0) they are those of the motion that
// follows, so that a restart on a kink sees what comes after it. The acceleration is the closed
// form of the motion: 0 for Static and Linear, -A w^2 sin(w s) for Oscillate, -w^2 (offset -
// centre) for Circle.
PrescribedPoint attachment_point(const Model& model, int attachment, double t);

}  // namespace pbdbench::ref_dae
