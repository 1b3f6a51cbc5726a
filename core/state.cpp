#include "core/state.hpp"

namespace pbdbench {

State rest_state(const Model& model) {
  State s;
  s.x = model.rest_positions;
  s.v = Points::Zero(model.rest_positions.rows(), 3);
  s.lambda.assign(model.constraints.size(), 0.0);
  for (const Attachment& a : model.attachments) {
    s.x.row(a.particle) = attachment_target(model, a, 0.0).transpose();
  }
  return s;
}

}  // namespace pbdbench
