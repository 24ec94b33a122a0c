"""HVRNN's evaluation protocol (Ghorbani et al.): attribute-labelled angle sequences,
the attribute classifiers, the denoising autoencoder, labelling unlabelled clips, and
the Inception Score / FID evaluation. The models themselves (HVRNN, ERD, QuaterNet)
are in ``generation.models``."""
