"""Whether a new checkpoint learnt what the study's other checkpoints learnt from: the same
kind of control, the same motion data, prepared the same way.

One study holds models of one dataset: its held-out controls are the test takes of that
dataset's split, which a model trained on other data, or on the same files prepared
otherwise (another overlap, other contents), may have trained on, and its NAT clips are
those takes as that preparation reads them. So a checkpoint that differs is refused when
it is added, naming each difference and the ``python -m generation train`` options that
would prepare the data as the study's checkpoints were.
"""

from __future__ import annotations

from collections.abc import Callable

from generation import registry
from studyapp.models import Study

# The dataset options `python -m generation train` sets: each option as it is written,
# "" where the option is left out.
TRAIN_OPTIONS: dict[str, tuple[str, Callable[[object], str]]] = {
    "contents": ("--contents", lambda value: f"--contents {','.join(value)}" if value else ""),
    "reverse": ("--reverse", lambda value: "--reverse" if value else ""),
    "overlap": ("--overlap", lambda value: f"--overlap {value:g}"),
    "scale": ("--scale", lambda value: f"--scale {value:g}" if value is not None else ""),
    "up": ("--up", lambda value: f"--up {value}" if value else ""),
    "mirror_pairs": ("--mirror-pairs", lambda value: "--mirror-pairs " + ",".join(
        f"{left}:{right}" for left, right in value.items()) if value else ""),
}
# Follows from mirror_pairs where the training command set it; listed only where it differs on its own.
DERIVED = {"root"}


def _shown(value: object) -> str:
    if isinstance(value, (list, tuple)):
        return ",".join(map(str, value))
    return f"{value:g}" if isinstance(value, float) else str(value)


def option_differences(new: dict, study: dict) -> list[str]:
    """Each dataset option where ``new`` differs from ``study``, in words."""
    names = [name for name in {**study, **new} if new.get(name) != study.get(name)]
    if any(name in TRAIN_OPTIONS for name in names):
        names = [name for name in names if name not in DERIVED]
    return [f"{name} {_shown(new.get(name))} in this checkpoint, {_shown(study.get(name))} in the study's" for name in names]


def matching_train_options(study: dict) -> str:
    """The ``train`` options that prepare the data as ``study`` (dataset options) says,
    and those to leave out."""
    written = {option: write(study.get(name)) for name, (option, write) in TRAIN_OPTIONS.items()}
    given = " ".join(text for text in written.values() if text)
    left_out = [option for option, text in written.items() if not text]
    return given + (f" (without {', '.join(left_out[:-1])}{' or ' if len(left_out) > 1 else ''}{left_out[-1]})"
                    if left_out else "")


def data_mismatch(study: Study, control: str, dataset_options: dict, fingerprint: str) -> str | None:
    """Why a checkpoint controlled by ``control`` (``registry.PATH`` or ``registry.LABELS``)
    that learnt from the data of ``fingerprint``, prepared by ``dataset_options``, does not
    fit ``study``'s other checkpoints; None where it fits (or is the first)."""
    others = [s for s in study.systems.exclude(checkpoint="") if s.kind in registry.MODELS]
    if not others:
        return None
    names = ", ".join(s.name for s in others)
    first = others[0].metadata
    theirs = registry.MODELS[others[0].kind].control
    if control != theirs:
        follows = {registry.PATH: "a path", registry.LABELS: "action and style labels"}
        return (f"it follows {follows[control]}, and the study's checkpoints ({names}) follow "
                f"{follows[theirs]}: one study holds one kind of model")
    differences = option_differences(dataset_options, first["dataset_options"])
    if differences:
        match = "" if control != registry.PATH else (
            f" Train it with: python -m generation train FOLDER ... {matching_train_options(first['dataset_options'])}")
        return (f"it learnt from data prepared otherwise than the study's checkpoints ({names}): "
                + "; ".join(differences) + f".{match}")
    if fingerprint != first.get("data_fingerprint"):
        return (f"it learnt from other motion files than the study's checkpoints ({names}), prepared the same way "
                f"(data fingerprint {fingerprint[:12]} here, {first.get('data_fingerprint', '')[:12]} there): a "
                "held-out take of one could be a training take of the other; train it on the same folders")
    return None


__all__ = ["data_mismatch", "matching_train_options", "option_differences"]
