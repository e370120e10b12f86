"""`plem view`: the arm in 3D in a local web page (viser), live from shared memory or DDS, or replayed from bags."""
