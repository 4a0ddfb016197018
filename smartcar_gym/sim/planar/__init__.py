"""The planar engine: rigid cars in the plane (x, y, yaw), simulated in numpy arrays over N cars."""
