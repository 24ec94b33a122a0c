"""HVRNN (Ghorbani et al.) and what its evaluation needs: attribute-labelled angle
sequences, attribute classifiers, the denoising autoencoder, the ERD and QuaterNet
baselines, and the Inception Score / FID evaluation."""
