"""Image files in and out, Warp-free: tone maps and atomic writers of PNG, JPEG, NPY, PFM, EXR and GIF
(``files``), the Radiance HDR codec (``hdr``), and environment maps read from any of them into the
host model (``environment``). Scene files are ``io/``'s."""
