"""The training data made of motion: finding BVH files and their labels, the dataset's
options, take splits, the built dataset with its cache and windows, takes and augmentation."""
