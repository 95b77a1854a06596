"""The process around the renderer: threads, signals, progress, Warp's initialisation.

``threads`` (cancellable worker threads), ``signals`` (Ctrl-C and SIGTERM as a stop flag),
``progress`` (tqdm bars and progress callbacks), ``warp_init`` (Warp initialised once, quietly).
"""
