// A dispatch of more workgroups than Vulkan promises in one dimension (65,535: Intel's and
// lavapipe's limit; a pass over 10^8 segments takes 390,625 workgroups of 256) comes as rows of
// 65,535 (vk::dispatch_workgroups, lib/render/vulkan/shaders.hpp). The workgroup's place in the
// dispatch, counted row by row; the last row's workgroups past the count are the caller's to
// skip.
uint flat_workgroup() {
  return gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
}
