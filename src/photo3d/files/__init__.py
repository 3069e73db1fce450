"""Touching the file system safely, and being interrupted safely.

``gate``: what a write may reach (no link, no FIFO, never the command's inputs) and
the lock that keeps a folder's record whole; ``atomic``: the one way photo3d writes a
file (temporary sibling, then rename), through the gate;
``staging``: output folders written in a temporary sibling and moved into place,
never replacing what photo3d did not write; ``rename``: the no-replace renames they
rest on; ``folders``: which files of an input folder count; ``download``: weights
fetched once into the cache; ``signals``: Ctrl-C and SIGTERM become exceptions so
every temporary is cleaned up. See ``docs/guarantees.md``.
"""
