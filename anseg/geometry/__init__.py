"""The geometry the descriptors and the eigenbasis are made of: ray casting, the shape diameter, geodesic and
spectral solves, diffusion over the surface, and the coarse proxy that large meshes are read on."""
