"""Spatial queries on triangle meshes: exact closest points (``closest``: a numba BVH,
``bvh``, ``bvh_query``, ``point_triangle``), barycentric coordinates (``barycentric``) and
projection along directions by Embree rays (``bake``)."""
