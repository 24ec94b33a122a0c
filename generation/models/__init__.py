"""The motion models, one module per model, on the bases of ``base``, ``path`` and
``attribute``; ``flows``, ``layers``, ``rotations``, ``losses``, ``kinematics`` and
``initial_state`` are their shared parts. Which kinds exist, and their presets, is
``generation.registry``'s table."""
