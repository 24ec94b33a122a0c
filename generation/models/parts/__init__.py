"""The models' shared building blocks: layers, flows, losses, noise, precision, the learned
initial state, kinematics and rotations; the model kinds one floor up import them."""
