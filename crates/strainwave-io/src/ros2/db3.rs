//! rosbag2 SQLite storage (`.db3`): the `topics` table names each topic's type and
//! serialization; `message_definitions` (rosbag2 schema 4 and later) holds the type's
//! `ros2msg` text, else a built-in definition is used (see `msg_def`). Messages are read
//! in pages of [`DB3_PAGE_ROWS`] rows by increasing `id` (the order they were written),
//! so memory is one page whatever the file size.

use std::borrow::Cow;
use std::collections::{HashMap, VecDeque};
use std::path::{Path, PathBuf};

use rusqlite::{Connection, OpenFlags};

use super::source::{ChannelInfo, RawMessage, Registry, DB3_PAGE_ROWS};
use crate::error::IoError;

/// The messages of one `.db3` file.
pub struct Db3Stream {
    path: PathBuf,
    conn: Connection,
    topics: HashMap<i64, usize>,
    page: VecDeque<RawMessage>,
    last_id: i64,
    done: bool,
}

fn sql_error(path: &Path, e: rusqlite::Error) -> IoError {
    IoError::Csv { path: path.to_path_buf(), msg: format!("SQLite: {e}") }
}

impl Db3Stream {
    /// Opens `file` read-only and registers its topics; `path` names it in errors (the
    /// log's own file, where `file` is its decompressed copy).
    pub fn open(file: &Path, path: &Path, registry: &mut Registry) -> Result<Self, IoError> {
        let flags = OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX;
        let conn = Connection::open_with_flags(file, flags).map_err(|e| sql_error(path, e))?;
        let err = |e| sql_error(path, e);
        let mut definitions: HashMap<String, (String, String)> = HashMap::new();
        let has_definitions: bool =
            conn.query_row(
                "SELECT count(*) FROM sqlite_master WHERE type='table' AND name='message_definitions'",
                [],
                |r| r.get::<_, i64>(0),
            )
            .map_err(|e| match e {
                rusqlite::Error::SqliteFailure(..) => {
                    IoError::Csv { path: path.to_path_buf(), msg: format!("not a rosbag2 SQLite file ({e})") }
                }
                e => err(e),
            })? > 0;
        if has_definitions {
            let mut st = conn
                .prepare("SELECT topic_type, encoding, encoded_message_definition FROM message_definitions")
                .map_err(err)?;
            let rows = st
                .query_map([], |r| Ok((r.get::<_, String>(0)?, r.get::<_, String>(1)?, r.get::<_, String>(2)?)))
                .map_err(err)?;
            for row in rows {
                let (ty, encoding, text) = row.map_err(err)?;
                definitions.insert(ty, (encoding, text));
            }
        }
        let mut topics = HashMap::new();
        let mut st = conn
            .prepare("SELECT id, name, type, serialization_format FROM topics")
            .map_err(|e| IoError::Csv { path: path.to_path_buf(), msg: format!("not a rosbag2 SQLite file ({e})") })?;
        let rows = st
            .query_map([], |r| {
                Ok((r.get::<_, i64>(0)?, r.get::<_, String>(1)?, r.get::<_, String>(2)?, r.get::<_, String>(3)?))
            })
            .map_err(err)?;
        for row in rows {
            let (id, topic, type_name, format) = row.map_err(err)?;
            let (schema_encoding, schema) = match definitions.get(&type_name) {
                Some((encoding, text)) if !text.is_empty() => (encoding.clone(), text.clone().into_bytes()),
                _ => ("ros2msg".to_string(), Vec::new()),
            };
            let info = ChannelInfo { topic, type_name, schema_encoding, schema, message_encoding: format };
            topics.insert(id, registry.intern(info));
        }
        drop(st);
        Ok(Self { path: path.to_path_buf(), conn, topics, page: VecDeque::new(), last_id: i64::MIN, done: false })
    }

    fn fill(&mut self) -> Result<(), IoError> {
        let err = |e| sql_error(&self.path, e);
        let mut st = self
            .conn
            .prepare_cached("SELECT id, topic_id, timestamp, data FROM messages WHERE id > ?1 ORDER BY id LIMIT ?2")
            .map_err(err)?;
        let mut rows = st.query((self.last_id, DB3_PAGE_ROWS)).map_err(err)?;
        let mut n = 0;
        while let Some(r) = rows.next().map_err(err)? {
            let id: i64 = r.get(0).map_err(err)?;
            let topic: i64 = r.get(1).map_err(err)?;
            let t: i64 = r.get(2).map_err(err)?;
            let data: Vec<u8> = r.get(3).map_err(err)?;
            self.last_id = id;
            n += 1;
            let Some(&channel) = self.topics.get(&topic) else {
                return Err(IoError::Csv {
                    path: self.path.clone(),
                    msg: format!("message id {id} has topic_id {topic}, which the topics table does not list"),
                });
            };
            self.page.push_back(RawMessage { channel, log_time_ns: t.max(0) as u64, data: Cow::Owned(data) });
        }
        self.done = n < DB3_PAGE_ROWS;
        Ok(())
    }

    /// The next message; `Ok(None)` at the end.
    pub fn next(&mut self) -> Result<Option<RawMessage>, IoError> {
        if self.page.is_empty() && !self.done {
            self.fill()?;
        }
        Ok(self.page.pop_front())
    }
}
