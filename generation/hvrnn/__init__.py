"""HVRNN (Ghorbani et al.) and what its evaluation needs: attribute-labelled angle
sequences, attribute classifiers, the denoising autoencoder, the ERD and QuaterNet
baselines, and the Inception Score / FID evaluation."""

# The model registry (generation.models) imports this package's models, which in turn
# build on generation.models' base classes; importing the registry first, whichever
# module is imported first, lets that cycle resolve.
from .. import models as _registry  # noqa: E402,F401
