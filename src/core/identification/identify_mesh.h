/**
 * @file identify_mesh.h
 * @brief A joint with a compliant mesh identified from a recording of its own motion: the start of a fit for teeth that
 *        are springs (mesh_stiffness > 0) — the bodies, the mesh's stiffness and damping, the backlash between its
 *        flanks, the static friction — by linear least squares, from the data alone. No ROS dependency.
 *
 * How it is computed and what it guarantees: docs/model.md, Part 4, "Initial estimates of a compliant mesh".
 */
#pragma once

#include "backlash_servo/identification/identification.h"

namespace backlash_servo
{
/**
 * The initial estimates of a joint with a compliant mesh (InitialEstimates::mesh_stiffness and mesh_damping set; the
 * restitution has no meaning here). Throws InvalidParameterError naming what is missing: the checks of
 * samplePeriod(), too few samples with both bodies moving, a mesh pressed on one flank only (the recording needs
 * contact on both), or a mesh stiffness that does not come out positive (the contact is not resolved by the samples).
 */
InitialEstimates estimateCompliantInitial(const Recording& data, const IdentificationSettings& settings);

}  // namespace backlash_servo
