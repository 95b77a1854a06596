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
  loses them in denormals; the fov (degrees) lies in [MIN_FOV, 180);
* the image plane's half-size (focus x tan(fov/2), times height/width for tall images) is at most
  MAX_IMAGE_PLANE: the kernel normalises vectors to it, squaring their components, and float32
  squares overflow beyond 1.8e19;
* a triangle's longest edge is at most MAX_TRIANGLE_EDGE: the kernel squares its cross product
  (about edge^4: the geometric normal, areas) and forms triple products of edge-sized and
  distance-sized numbers in the hit test (about edge^2 x distance), in float32; a square of
  half-size 4e9 shades black and one of 4e12 is missed (tests/hardening/test_bounds_memory_and_signals.py).

The render settings have bounds too (``rendering.settings.check_args`` applies them for the API,
the command line and the viewer alike), so that no setting can wrap a kernel's int32 or make
memory or time grow without limit:

* samples per pixel at most MAX_SPP, depth and roulette depth at most MAX_DEPTH, worker threads at
  most MAX_THREADS, pixels per launch at most MAX_TILE_PIXELS, progressive batches at most
  MAX_BATCHES (each holds a float64 image).
"""

MAX_RADIANCE = 1e30
# an environment map's turn about the up axis, in degrees either way (Sky, --env-rotate, the viewer):
# a million degrees is thousands of turns already, past any intent
MAX_ENV_ROTATE = 1e6
MIN_IOR, MAX_IOR = 1e-3, 1e3
MAX_COORDINATE = 1e15
# The camera may stand and focus farther out than geometry may lie, so that every loadable scene,
# up to +-MAX_COORDINATE, can be framed from outside (Camera.frame): products of two camera-sized
# numbers (1e34) stay finite in float32 too.
MAX_CAMERA_COORDINATE = 100 * MAX_COORDINATE
MIN_FOCUS = 1e-9
# The narrowest lens tested (docs/limits.md); narrower ones put every pixel's ray on one float32
# direction, and framing a scene through them stood the camera beyond MAX_CAMERA_COORDINATE.
MIN_FOV = 1e-4
MIN_DIRECTION = 1e-30
MAX_IMAGE_PLANE = 1e18
# edge^4 = 1e36 leaves a factor 340 below float32's 3.4e38 (a triangle's normal overflowed at an
# edge of 4.3e9); edge^2 x the farthest camera (1e17) = 1e35 in the hit test's triple products.
MAX_TRIANGLE_EDGE = 1e9

MAX_SPP = 1 << 20
MAX_DEPTH = 4096
MAX_THREADS = 1024
MAX_TILE_PIXELS = 1 << 22       # a launch's own buffers: 4M pixels of float32 RGB and more
MAX_BATCHES = 64
# The live viewer's view (width x height): its refined image is 8 float64 batch sums, at most
# 8 x 2**21 x 3 x 8 bytes = 384 MiB (docs/viewer.md), where 4096 x 4096 would take 6-7.4 GB.
MAX_VIEW_PIXELS = 1 << 21

# frames per second of an animated glTF: from one frame per 1000 s (a slow time-lapse) to a million a
# second; frame k at k / fps seconds then stays finite for every frame number (5e-324 made it inf)
MIN_FPS, MAX_FPS = 1e-3, 1e6
