"""Datasets: rosbags and dataset folders -> preprocessed frames with (v, w) labels."""
