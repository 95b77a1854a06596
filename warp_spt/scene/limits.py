"""Bounds on the values that reach a kernel (no imports: the command line reads them at start-up).

They are chosen so that every product the kernel forms stays finite in float32 (docs/limits.md,
"Input and resource limits"):

* reflectance colours (diffuse, reflect, refract) lie in [0, 1], so the path throughput never
  grows; a surface cannot return more light than it receives;
* emission and sky radiance are at most MAX_RADIANCE, so one sample's radiance, at most
  MAX_DEPTH x MAX_RADIANCE x max(1, texture) = 4.1e33, stays far below float32's 3.4e38;
* the index of refraction lies in [MIN_IOR, MAX_IOR]: 1/ior and Schlick's terms stay finite;
* geometry coordinates stay within +-MAX_COORDINATE (see warp_spt.io.obj), the camera's position,
  focus distance and aperture within MAX_CAMERA_COORDINATE (so that any scene can be framed from
  outside); the focus distance is at least MIN_FOCUS; directions (view, up) have a largest component in
  [MIN_DIRECTION, MAX_COORDINATE], so that normalising them on the host neither overflows nor
  loses them in denormals;
* the image plane's half-size (focus x tan(fov/2), times height/width for tall images) is at most
  MAX_IMAGE_PLANE: the kernel normalises vectors to it, squaring their components, and float32
  squares overflow beyond 1.8e19.
"""

MAX_RADIANCE = 1e30
MIN_IOR, MAX_IOR = 1e-3, 1e3
MAX_COORDINATE = 1e15
# The camera may stand and focus farther out than geometry may lie, so that every loadable scene,
# up to +-MAX_COORDINATE, can be framed from outside (Camera.frame): products of two camera-sized
# numbers (1e34) stay finite in float32 too.
MAX_CAMERA_COORDINATE = 100 * MAX_COORDINATE
MIN_FOCUS = 1e-9
MIN_DIRECTION = 1e-30
MAX_IMAGE_PLANE = 1e18
