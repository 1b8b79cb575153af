"""Datasets: rosbags and dataset folders -> preprocessed frames with (v, w) labels.

- bags.read_frames / read_bag: any ROS1 bag or ROS2 bag (sqlite3, mcap) or DLS folder -> FrameSet
- preprocess: crop + resize (training and drive time), DrivePreprocessor for the simulator's brain
- folder: DeepLearningStudio dataset folders (read, convert to a bag); bagwrite: BagWriter
- augment, split: training-time augmentation and validation splits; inspect: what a bag holds
"""
