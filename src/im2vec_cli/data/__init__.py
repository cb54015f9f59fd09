"""Datasets and the builders that turn fonts, MNIST and SVG sets into PNG folders."""
