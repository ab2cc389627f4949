"""footforge: simulation models, validation and training for robots with passive adaptive feet."""

import os as _os

# footforge authors models with dm_control.mjcf and never renders through dm_control; without this
# dm_control probes for an X display (GLFW) at import and warns on headless machines.
_os.environ.setdefault("MUJOCO_GL", "disable")

__version__ = "0.1.0"
