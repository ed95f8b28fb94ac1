"""MJCF models shipped with mjtraj, installed as the package `mjtraj.assets`."""
