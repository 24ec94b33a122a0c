"""The registry entry of the "toy" kind: data only, no torch, so listing kinds stays cheap."""

from generation.registry import PATH, ModelKind, Preset

KIND = ModelKind(
    "toy_motion_model.model:ToyPathModel", "Toy MLP", PATH,
    training={"learning_rate": 1e-3, "grad_clip": 1.0, "batch_size": 32},
    presets={"paper": Preset(), "cpu": Preset(model={"hidden": 64})},
)
