"""MJCF models of the lab's robots, shipped as package data (``labsupport.models``).

Load them with :func:`labsupport.plants.load_model`; never by a path relative to the
working directory.
"""
