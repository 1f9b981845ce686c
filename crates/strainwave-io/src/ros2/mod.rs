//! ROS 2 logs (MCAP, rosbag2 SQLite and folders) read as recordings: messages decoded
//! by the definitions stored in the log, topics aligned on one clock.

pub mod align;
#[cfg(feature = "mcap")]
pub mod bag;
#[cfg(feature = "mcap")]
pub mod cdr_walk;
#[cfg(feature = "sqlite")]
mod db3;
#[cfg(feature = "mcap")]
pub mod msg_def;
#[cfg(feature = "mcap")]
mod record_check;
#[cfg(feature = "mcap")]
pub mod source;
#[cfg(feature = "mcap")]
pub mod unpacked;
