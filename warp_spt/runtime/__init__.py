"""The process around the renderer: threads, signals, progress, Warp's start, caches.

``threads`` (cancellable worker threads), ``signals`` (Ctrl-C and SIGTERM as a stop flag),
``progress`` (tqdm bars and progress callbacks), ``warp_init`` (Warp initialised once, quietly),
``kernel_cache`` (the one locked cache of built samplers and compiled kernels), ``kernel_index`` (the
fast kernel's compiled object found by a key of our own), ``extras`` (how to install an optional
part) and ``memory`` (large freed host arrays returned to the system).
"""
