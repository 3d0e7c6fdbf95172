//! The one error type of the bag reader. Every variant names the file; those about one message
//! also name its topic and its 0-based index among that topic's messages, because that is what a
//! person needs to find it again (`mcap cat --topics T`, or the n-th message in Foxglove).

use std::path::PathBuf;

/// Why a ROS 2 MCAP recording could not be read as a drive.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BagError {
    /// The file could not be opened or read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A chunk uses a compression this build cannot read.
    #[error(
        "{path}: a chunk is compressed with `{compression}`, which this build cannot read \
         (supported: none, zstd, lz4); re-record or convert with `mcap compress`"
    )]
    Compression {
        /// The file.
        path: PathBuf,
        /// The compression named in the chunk.
        compression: String,
    },
    /// The MCAP container itself is malformed (bad magic, truncated record, CRC mismatch, …).
    #[error("{path}: MCAP container, after {messages} messages read: {source}")]
    Mcap {
        /// The file.
        path: PathBuf,
        /// Messages read successfully before the error.
        messages: u64,
        /// The reader's error.
        source: mcap::McapError,
    },
    /// One message could not be decoded.
    #[error("{path}: topic {topic}, message #{index} ({kind}): {message}")]
    Message {
        /// The file.
        path: PathBuf,
        /// Its topic.
        topic: String,
        /// 0-based index among the topic's messages, in file order.
        index: u64,
        /// The message type, e.g. `sensor_msgs/msg/PointCloud2`.
        kind: String,
        /// What is wrong.
        message: String,
    },
    /// The requested topic is not in the file.
    #[error("{path}: no topic {topic}; the file has: {available}")]
    UnknownTopic {
        /// The file.
        path: PathBuf,
        /// The requested topic.
        topic: String,
        /// The topics present, `topic (type, count)`, comma-separated.
        available: String,
    },
    /// A topic has another type than the one needed, or the CDR encoding is not used.
    #[error("{path}: topic {topic} is `{found}` ({encoding}); expected `{expected}` in cdr")]
    WrongType {
        /// The file.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// Its schema name.
        found: String,
        /// Its message encoding.
        encoding: String,
        /// What was needed.
        expected: &'static str,
    },
    /// No topic of a needed type, or several with none chosen.
    #[error("{path}: {message}; the file has: {available}")]
    Topic {
        /// The file.
        path: PathBuf,
        /// What is missing or ambiguous, and how to choose.
        message: String,
        /// The topics present, `topic (type, count)`, comma-separated.
        available: String,
    },
    /// A folder given as the recording that is not a rosbag2 folder of one MCAP file.
    #[error("{path}: {message}")]
    Folder {
        /// The folder.
        path: PathBuf,
        /// What it holds, and what to do.
        message: String,
    },
    /// The poses cannot be built from the chosen source (no tf chain, no fixes, …).
    #[error("{path}: poses: {message}")]
    Poses {
        /// The file.
        path: PathBuf,
        /// What is missing, and what was found.
        message: String,
    },
}
