// Camera in the archive's frame coordinates (double precision) and the camera-relative view the
// GPU gets: positions become integers of half metres minus the camera's, so UTM-sized
// coordinates keep sub-millimetre precision and shared vertices stay bit-identical.
#pragma once
#include <cstdint>

#include "gpu_types.h"
#include "terrain/format.h"

namespace terrain::view {

struct Camera {
  double position[3] = {0, 0, 0};  // frame x (east), y (north), height, metres
  double yaw = 0;                  // heading, radians, 0 = north, pi/2 = east
  double pitch = 0;                // radians, negative looks down
  double fovy = 1.0471975511965976;  // vertical field of view, radians (60 degrees)
  double near_m = 0.5;
};

// Points the camera at `target` (frame coordinates).
void look_at(Camera& camera, const double target[3]);
// Unit forward vector in frame axes.
void camera_forward(const Camera& camera, double out[3]);

// Fills the camera-dependent members of `u`: view_proj, planes, cam_hm, cam_frac (incl. pixels per
// radian), viewport, wrap_origin.
void fill_view_uniforms(const Camera& camera, const WorldInfo& world, uint32_t width, uint32_t height,
                        FrameUniforms& u);

// Right, up and forward unit vectors (frame axes) of the view fill_view_uniforms builds.
void camera_basis(const Camera& camera, double right[3], double up[3], double forward[3]);
// Camera-relative point seen at pixel centre (px, py) with reversed-Z depth `depth` (> 0).
void unproject(const Camera& camera, uint32_t width, uint32_t height, double px, double py, float depth, double out[3]);

// Pixels per radian of a vertical field of view over `height` pixels (screen-space error scale).
double pixels_per_radian(double fovy, uint32_t height);

// Projects a camera-relative point with u.view_proj; returns false behind the camera.
bool project(const FrameUniforms& u, const float rel[3], double& px, double& py, double& depth);

}  // namespace terrain::view
