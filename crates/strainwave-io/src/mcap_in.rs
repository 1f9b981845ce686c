//! MCAP input: ROS 2 sensor_msgs/msg/JointState (CDR) and JSON messages as recording columns.
