"""Default topics of our recordings (docs/CONVENTIONS.md); a recipe may name others."""
IMAGE_TOPIC = "/F1ROS/cameraL/image_raw"
COMPRESSED_IMAGE_TOPIC = "/F1ROS/cameraL/image_raw/compressed"
COMMAND_TOPIC = "/F1ROS/cmd_vel"
ODOMETRY_TOPIC = "/F1ROS/odom"

# Tried in order when no image topic is named.
DEFAULT_IMAGE_TOPICS = (IMAGE_TOPIC, COMPRESSED_IMAGE_TOPIC)
METADATA_TOPIC = "/pilotlab/metadata"   # one JSON std_msgs/String at time 0: how the recording was made
