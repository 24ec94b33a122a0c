"""The motion models, one module per model, on the bases of ``motion_model``, ``path`` and
``attribute``; ``parts/`` holds their shared building blocks (flows, layers, rotations,
losses, kinematics, noise, precision, the initial state). Which kinds exist, and their presets, is
``generation.registry``'s table."""
