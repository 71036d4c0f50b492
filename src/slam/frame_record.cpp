#include "slam/frame_record.h"

namespace cslam {

LiveReference live_reference(const FrameRecord& record) {
  LiveReference out{record.reference.get(), record.T_cam_ref};
  while (out.keyframe && out.keyframe->bad && out.keyframe->parent) {
    out.T_cam_ref = out.T_cam_ref * out.keyframe->T_cam_parent;
    out.keyframe = out.keyframe->parent.get();
  }
  return out;
}

void reanchor_culled(std::vector<FrameRecord>& records) {
  for (FrameRecord& r : records) {
    while (r.reference && r.reference->bad && r.reference->parent) {
      r.T_cam_ref = r.T_cam_ref * r.reference->T_cam_parent;
      r.reference = r.reference->parent;
    }
  }
}

}  // namespace cslam
