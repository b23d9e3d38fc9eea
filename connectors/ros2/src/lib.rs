//! ROS 2 for TRACE:
//! - the connector of `kind = "ros2"` that commands ROS 2 action servers ([`connector`]);
//! - action servers for a Rust system that serves its activities over ROS 2 ([`server`]: the
//!   ELAP simulator's arm and excavation in `deploy/ros2`);
//! - the action definitions of a ROS 2 installation turned into the catalogue entries the
//!   executive checks missions against before flight ([`definitions`], the paper's
//!   "autocoder"), from the interface language's own files ([`idl`]).
//!
//! Why the definitions are read here and not through a ROS 2 library: the pre-flight check
//! needs every field's type, range and default before anything runs, on machines that may have
//! no ROS 2 installed (a planner's); the `.action` and `.msg` files are the specification, and
//! their language is small. `tests/it/ros2.rs` checks what this reads against what `rclpy`
//! reports for every definition of `test_msgs`.

pub mod connector;
pub mod definitions;
pub mod idl;
pub mod server;

pub use connector::Ros2Connector;
pub use definitions::{Action, Definitions, catalogue_of};
pub use idl::IdlError;
pub use server::{Request, Ros2Server, ServeError, ServedGoal};
