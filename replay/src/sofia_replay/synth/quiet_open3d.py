"""Imported first by ``sofia_replay.synth``: Open3D prints only its errors, not its warnings."""

import open3d as o3d

o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
