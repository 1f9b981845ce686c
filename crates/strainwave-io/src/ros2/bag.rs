//! A ROS 2 log (MCAP file, rosbag2 `.db3` or folder) read as a recording.
//!
//! Columns:
//!
//! - `time`, s: the clock (see [`crate::ros2::align`]); a message's time is its
//!   `header.stamp` where it has one ([`TimeSource::Header`]), else its log time.
//! - `sensor_msgs/msg/JointState`: `<joint>.position|velocity|effort`;
//!   `control_msgs/msg/DynamicJointState`: `<joint>.<interface>` (`j1.motor_position`).
//!   When two topics give the same such name, each is prefixed by its topic
//!   (`/joint_states/j1.position`).
//! - Any other `ros2msg` type in CDR: `<topic>/<field path>` for every numeric field,
//!   nested fields and array items by dotted path (`/wrench/wrench.force.x`,
//!   `/arm/gains.2`); the top-level header is the time, not a column.
//! - JSON messages: `<topic>.<path>` as [`crate::mcap_in::flatten_json`] names them.
//! - Channels of another encoding are skipped with a warning naming topic and schema.
//!
//! Two passes over the file: the first finds the columns, the topics' rates and how far
//! times run out of order; the second decodes again and streams rows. Memory is one
//! decompressed chunk (or SQLite page), the messages within the largest out-of-order
//! step (zero when times increase), and the clock rows within the largest `max_gap`.
//! A damaged file gives its rows up to the damage, then an error naming where it stopped;
//! an MCAP file cut short (no footer) gives the messages before the cut, with a warning.

use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};
use std::path::{Path, PathBuf};

use super::align::{Align, Aligner, ClockSource};
use super::cdr_walk::{walk, Decoded, Naming};
use super::msg_def::MsgDef;
use super::source::{ChannelInfo, MessageStream, RawMessage, Registry};
use crate::error::IoError;
use crate::read_options::{ReadOptions, TimeSource};

/// Layout caches larger than this are emptied (a message with a changing string).
const MAX_LAYOUTS: usize = 1024;
/// Default `max_gap`: this many mean periods of the topic…
const DEFAULT_GAP_PERIODS: f64 = 4.0;
/// …and at most this, ns.
const DEFAULT_GAP_MAX_NS: i64 = 10_000_000_000;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Special {
    JointState,
    DynamicJointState,
    Transforms,
    Other,
}

enum Kind {
    Cdr { def: Box<MsgDef>, special: Special, layouts: HashMap<Vec<u8>, Vec<usize>> },
    Json,
    Skip(String),
}

struct ChannelState {
    kind: Kind,
    topic: usize,
    selected: bool,
}

#[derive(Default)]
struct TopicStat {
    name: String,
    head: String,
    messages: u64,
    with_values: u64,
    /// Messages with values read on the second pass (the summary's count).
    read: u64,
    first_ns: i64,
    last_ns: i64,
    long_arrays: Vec<String>,
    skipped: Option<String>,
    /// Messages that give a column a second value at one time (on one clock a time has
    /// one row, with the first value), and the first such time, ns.
    same_time: (u64, i64),
}

/// Column ids by (topic, name as decoded).
#[derive(Default)]
struct Names {
    ids: HashMap<(usize, String), usize>,
    /// (topic, bare name, joint-style name that may clash).
    entries: Vec<(usize, String, bool)>,
}

fn kind_of(info: &ChannelInfo) -> Kind {
    let enc = info.message_encoding.to_ascii_lowercase();
    if enc == "json" {
        return Kind::Json;
    }
    if enc != "cdr" {
        return Kind::Skip(format!("message encoding `{}` is not read (cdr and json are)", info.message_encoding));
    }
    if !info.schema_encoding.is_empty() && info.schema_encoding != "ros2msg" {
        return Kind::Skip(format!("unknown schema encoding `{}` (ros2msg is read)", info.schema_encoding));
    }
    let text = String::from_utf8_lossy(&info.schema);
    match MsgDef::parse(&info.type_name, &text) {
        Ok(def) => {
            let special = match def.root().name.as_str() {
                "sensor_msgs/JointState" => Special::JointState,
                "control_msgs/DynamicJointState" => Special::DynamicJointState,
                "tf2_msgs/TFMessage" => Special::Transforms,
                _ => Special::Other,
            };
            Kind::Cdr { def: Box::new(def), special, layouts: HashMap::new() }
        }
        Err(e) => Kind::Skip(format!("schema `{}` cannot be used: {e}", info.type_name)),
    }
}

/// Names of the values of one layout: `(name, joint-style)`. A transform of a
/// `TFMessage` is named by its frame (`base_link.translation.x`), not its place in the
/// message: messages of one topic carry different frames (each publisher its own).
fn bare_names(special: Special, naming: &Naming) -> Vec<(String, bool)> {
    let strings: HashMap<&str, &str> = naming.strings.iter().map(|(p, s)| (p.as_str(), s.as_str())).collect();
    naming
        .paths
        .iter()
        .map(|path| {
            let parts: Vec<&str> = path.split('.').collect();
            match (special, parts.as_slice()) {
                (Special::JointState, [field @ ("position" | "velocity" | "effort"), i]) => {
                    strings.get(format!("name.{i}").as_str()).map(|j| (format!("{j}.{field}"), true))
                }
                (Special::DynamicJointState, ["interface_values", i, "values", k]) => {
                    let joint = strings.get(format!("joint_names.{i}").as_str());
                    let iface = strings.get(format!("interface_values.{i}.interface_names.{k}").as_str());
                    joint.zip(iface).map(|(j, f)| (format!("{j}.{f}"), true))
                }
                (Special::Transforms, ["transforms", i, rest @ ..]) => {
                    let frame = strings.get(format!("transforms.{i}.child_frame_id").as_str());
                    let rest = rest.strip_prefix(&["transform"]).unwrap_or(rest);
                    frame.filter(|f| !f.is_empty()).map(|f| (format!("{f}.{}", rest.join(".")), false))
                }
                _ => None,
            }
            .unwrap_or_else(|| (path.clone(), false))
        })
        .collect()
}

/// `(joint index, field)` of a JointState value path (`effort.2` → (2, 2)).
fn joint_state_rank(path: &str) -> (usize, usize) {
    let (field, index) = path.split_once('.').unwrap_or((path, ""));
    let field = ["position", "velocity", "effort"].iter().position(|f| *f == field).unwrap_or(3);
    (index.parse().unwrap_or(usize::MAX), field)
}

/// One message waiting in the reorder buffer.
struct Held {
    t_ns: i64,
    seq: u64,
    topic: usize,
    values: Vec<(usize, f64)>,
}

impl PartialEq for Held {
    fn eq(&self, o: &Self) -> bool {
        (self.t_ns, self.seq) == (o.t_ns, o.seq)
    }
}
impl Eq for Held {}
impl PartialOrd for Held {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Held {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        (self.t_ns, self.seq).cmp(&(o.t_ns, o.seq))
    }
}

/// A ROS 2 log read row by row (see the module doc).
pub struct BagReader {
    path: PathBuf,
    columns: Vec<String>,
    warnings: Vec<String>,
    registry: Registry,
    channels: Vec<ChannelState>,
    topics: Vec<TopicStat>,
    topic_index: HashMap<String, usize>,
    names: Names,
    wanted: Vec<String>,
    use_header: bool,
    decoded: Decoded,
    values: Vec<(usize, f64)>,
    json: Vec<(String, f64)>,
    stream: MessageStream,
    aligner: Aligner,
    lateness_ns: i64,
    held: BinaryHeap<Reverse<Held>>,
    newest_ns: i64,
    seq: u64,
    messages: u64,
    last_log_ns: u64,
    rows_read: u64,
    finished: bool,
    stop: Option<IoError>,
    /// Per column: samples, first and last time (ns) in the first pass.
    column_spans: Vec<(u64, i64, i64)>,
    /// The time of each column's last value given to the clock, ns.
    column_last_ns: Vec<i64>,
    clock_topic: Option<String>,
}

impl BagReader {
    /// Opens a log and runs the first pass.
    pub fn open(path: &Path, options: &ReadOptions) -> Result<Self, IoError> {
        let mut r = Self {
            path: path.to_path_buf(),
            columns: vec!["time".into()],
            warnings: Vec::new(),
            registry: Registry::default(),
            channels: Vec::new(),
            topics: Vec::new(),
            topic_index: HashMap::new(),
            names: Names::default(),
            wanted: options.topics.clone(),
            use_header: options.time == TimeSource::Header,
            decoded: Decoded::default(),
            values: Vec::new(),
            json: Vec::new(),
            stream: MessageStream::open(path)?,
            aligner: Aligner::new(Align::None, ClockSource::Topic(0), &[]),
            lateness_ns: 0,
            held: BinaryHeap::new(),
            newest_ns: i64::MIN,
            seq: 0,
            messages: 0,
            last_log_ns: 0,
            rows_read: 0,
            finished: false,
            stop: None,
            column_spans: Vec::new(),
            column_last_ns: Vec::new(),
            clock_topic: None,
        };
        r.first_pass()?;
        r.plan(options)?;
        r.stream = MessageStream::open(path)?;
        r.messages = 0;
        Ok(r)
    }

    fn first_pass(&mut self) -> Result<(), IoError> {
        let mut newest = i64::MIN;
        loop {
            let msg = match self.stream.next(&mut self.registry) {
                Ok(Some(m)) => m,
                Ok(None) => break,
                Err(e) => {
                    if self.messages == 0 {
                        return Err(e);
                    }
                    // The second pass meets the same damage and reports it.
                    break;
                }
            };
            self.messages += 1;
            let Some((t, topic)) = self.decode(&msg, true)? else { continue };
            let stat = &mut self.topics[topic];
            if self.values.is_empty() {
                continue;
            }
            if stat.with_values == 0 {
                stat.first_ns = t;
            }
            stat.with_values += 1;
            stat.last_ns = stat.last_ns.max(t);
            // Each column's own samples: topics shared by publishers at different rates
            // (an arm and a gripper on `/joint_states`) give each column its own rate.
            for &(id, _) in &self.values {
                if self.column_spans.len() <= id {
                    self.column_spans.resize(id + 1, (0, i64::MAX, i64::MIN));
                }
                let (n, first, last) = &mut self.column_spans[id];
                (*n, *first, *last) = (*n + 1, (*first).min(t), (*last).max(t));
            }
            newest = newest.max(t);
            self.lateness_ns = self.lateness_ns.max(newest - t);
        }
        for (file, last_ns) in self.stream.cut_short() {
            let name = match file == &self.path {
                true => "the file".to_string(),
                false => format!("`{}`", file.file_name().unwrap_or_default().to_string_lossy()),
            };
            let read = match last_ns {
                Some(t) => format!("the messages before the cut are read, up to log time {} s", *t as f64 / 1e9),
                None => "no message of it is read".to_string(),
            };
            self.warnings.push(format!(
                "{name} ends before its footer (a recorder stopped before closing it, or a copy cut short): {read}"
            ));
        }
        Ok(())
    }

    fn topic_of(&mut self, info_topic: &str) -> usize {
        if let Some(&i) = self.topic_index.get(info_topic) {
            return i;
        }
        self.topics.push(TopicStat { name: info_topic.to_string(), ..Default::default() });
        self.topic_index.insert(info_topic.to_string(), self.topics.len() - 1);
        self.topics.len() - 1
    }

    /// Decodes one message into `self.values`; `None` for a skipped channel.
    fn decode(&mut self, msg: &RawMessage, first: bool) -> Result<Option<(i64, usize)>, IoError> {
        while self.channels.len() <= msg.channel {
            let info = &self.registry.channels[self.channels.len()];
            let kind = kind_of(info);
            let (topic_name, head) = (
                info.topic.clone(),
                format!(
                    "topic `{}` with schema `{}` (schema encoding `{}`), message encoding `{}`",
                    info.topic, info.type_name, info.schema_encoding, info.message_encoding
                ),
            );
            let selected = self.wanted.is_empty() || self.wanted.contains(&topic_name);
            let topic = self.topic_of(&topic_name);
            self.topics[topic].head = head;
            if let Kind::Skip(why) = &kind {
                if selected {
                    self.topics[topic].skipped = Some(why.clone());
                }
            }
            self.channels.push(ChannelState { kind, topic, selected });
        }
        let ch = &mut self.channels[msg.channel];
        let topic = ch.topic;
        if first {
            self.topics[topic].messages += 1;
        }
        self.values.clear();
        if !ch.selected {
            return Ok(None);
        }
        let log_ns = i64::try_from(msg.log_time_ns).unwrap_or(i64::MAX);
        self.last_log_ns = msg.log_time_ns;
        let topic_name = &self.topics[topic].name;
        let bad = |what: &str, e: &dyn std::fmt::Display| IoError::Csv {
            path: self.path.clone(),
            msg: format!("topic `{topic_name}`, message at log time {} s: {what}: {e}", msg.log_time_ns as f64 / 1e9),
        };
        let mut t = log_ns;
        match &mut ch.kind {
            Kind::Skip(_) => return Ok(None),
            Kind::Json => {
                crate::mcap_in::flatten_json(&msg.data, topic_name, &mut self.json).map_err(|e| bad("bad JSON", &e))?;
                for (name, v) in self.json.drain(..) {
                    let key = (topic, name);
                    let id = match self.names.ids.get(&key) {
                        Some(&id) => id,
                        None if first => {
                            self.names.entries.push((topic, key.1.clone(), false));
                            self.names.ids.insert(key, self.names.entries.len() - 1);
                            self.names.entries.len() - 1
                        }
                        None => return Err(changed(&self.path, &key.1)),
                    };
                    self.values.push((id, v));
                }
            }
            Kind::Cdr { def, special, layouts } => {
                let type_name = def.root().name.clone();
                if walk(def, &msg.data, &mut self.decoded, None).is_err() {
                    // Again with field paths, for the message.
                    let e = walk(def, &msg.data, &mut Decoded::default(), Some(&mut Naming::default()));
                    let e = e.err().map(|e| e.to_string()).unwrap_or_default();
                    return Err(bad(&format!("does not match its schema `{type_name}`"), &e));
                }
                if self.use_header {
                    if let Some(s) = self.decoded.stamp_ns.filter(|&s| s > 0) {
                        t = s;
                    }
                }
                if !layouts.contains_key(&self.decoded.layout_key) {
                    let mut naming = Naming::default();
                    let mut again = Decoded::default();
                    walk(def, &msg.data, &mut again, Some(&mut naming))
                        .map_err(|e| bad(&format!("does not match its schema `{type_name}`"), &e))?;
                    let names = bare_names(*special, &naming);
                    // New JointState columns go in joint by joint (wire order is field by field).
                    let mut order: Vec<usize> = (0..names.len()).collect();
                    if *special == Special::JointState {
                        order.sort_by_key(|&k| joint_state_rank(&naming.paths[k]));
                    }
                    let mut ids = vec![0; names.len()];
                    for k in order {
                        let (name, joint) = names[k].clone();
                        let key = (topic, name);
                        let id = match self.names.ids.get(&key) {
                            Some(&id) => id,
                            None if first => {
                                self.names.entries.push((topic, key.1.clone(), joint));
                                self.names.ids.insert(key, self.names.entries.len() - 1);
                                self.names.entries.len() - 1
                            }
                            None => return Err(changed(&self.path, &key.1)),
                        };
                        ids[k] = id;
                    }
                    if first {
                        for a in naming.long_arrays {
                            if !self.topics[topic].long_arrays.contains(&a) {
                                self.topics[topic].long_arrays.push(a);
                            }
                        }
                    }
                    if layouts.len() >= MAX_LAYOUTS {
                        layouts.clear();
                    }
                    layouts.insert(self.decoded.layout_key.clone(), ids);
                }
                let ids = &layouts[&self.decoded.layout_key];
                self.values.extend(ids.iter().copied().zip(self.decoded.values.iter().copied()));
            }
        }
        Ok(Some((t, topic)))
    }

    /// Column names, the clock and the warnings, from the first pass.
    fn plan(&mut self, options: &ReadOptions) -> Result<(), IoError> {
        if self.topics.is_empty() {
            let msg = match self.stream.cut_short().is_empty() {
                true => "no messages in the log",
                false => "the file ends before its first message (cut short)",
            };
            return Err(IoError::Csv { path: self.path.clone(), msg: msg.into() });
        }
        for want in &options.topics {
            if !self.topic_index.contains_key(want) {
                let have: Vec<&str> = self.topics.iter().map(|t| t.name.as_str()).collect();
                // In a file cut short the topic's messages may lie after the cut.
                let cut = match self.stream.cut_short().first() {
                    Some((_, Some(t))) => {
                        format!("; the log ends before its footer after log time {} s", *t as f64 / 1e9)
                    }
                    Some((_, None)) => "; the log ends before its footer".to_string(),
                    None => String::new(),
                };
                return Err(IoError::Csv {
                    path: self.path.clone(),
                    msg: format!("--topic: no message of topic `{want}` in the log (topics: {}){cut}", have.join(", ")),
                });
            }
        }
        // Joint-style names given by two topics are prefixed by their topic.
        let mut count: HashMap<&str, usize> = HashMap::new();
        for (_, name, joint) in &self.names.entries {
            if *joint {
                *count.entry(name.as_str()).or_default() += 1;
            }
        }
        let json: Vec<bool> = self.names.entries.iter().map(|(t, _, _)| self.is_json_topic(*t)).collect();
        for (k, (topic, name, joint)) in self.names.entries.iter().enumerate() {
            let topic = &self.topics[*topic].name;
            self.columns.push(if json[k] || (*joint && count[name.as_str()] == 1) {
                name.clone()
            } else {
                format!("{topic}/{name}")
            });
        }
        // The clock: the fastest topic, or a grid.
        let rate = |s: &TopicStat| {
            if s.with_values >= 2 && s.last_ns > s.first_ns {
                (s.with_values - 1) as f64 / ((s.last_ns - s.first_ns) as f64 * 1e-9)
            } else {
                0.0
            }
        };
        let mut clock = 0;
        for (i, s) in self.topics.iter().enumerate() {
            if s.with_values > 0 && (self.topics[clock].with_values == 0 || rate(s) > rate(&self.topics[clock])) {
                clock = i;
            }
        }
        let source = match options.resample_hz {
            Some(hz) if hz.is_finite() && hz > 0.0 => ClockSource::Grid(hz),
            Some(hz) => {
                return Err(IoError::Csv {
                    path: self.path.clone(),
                    msg: format!("--resample-hz must be positive, got {hz}"),
                })
            }
            None => {
                self.clock_topic = self.topics.get(clock).map(|t| t.name.clone());
                ClockSource::Topic(clock)
            }
        };
        let user_gap = match options.max_gap_s {
            Some(g) if g.is_finite() && g >= 0.0 => Some((g * 1e9).round() as i64),
            Some(g) => {
                return Err(IoError::Csv {
                    path: self.path.clone(),
                    msg: format!("--max-gap must be zero or positive, got {g}"),
                })
            }
            None => None,
        };
        let column_rate = |k: usize| match self.column_spans.get(k) {
            Some(&(n, first, last)) if n >= 2 && last > first => (n - 1) as f64 / ((last - first) as f64 * 1e-9),
            _ => 0.0,
        };
        let gaps: Vec<i64> = (0..self.names.entries.len())
            .map(|k| {
                user_gap.unwrap_or_else(|| {
                    let r = column_rate(k);
                    if r > 0.0 {
                        ((DEFAULT_GAP_PERIODS * 1e9 / r).round() as i64).min(DEFAULT_GAP_MAX_NS)
                    } else {
                        DEFAULT_GAP_MAX_NS
                    }
                })
            })
            .collect();
        self.aligner = Aligner::new(options.align, source, &gaps);
        // A topic whose times miss the clock topic's altogether gives only NaN: most
        // often header stamps and log times on different clocks.
        if options.align != Align::None {
            let c = &self.topics[clock];
            let span = |s: &TopicStat| format!("{}–{} s", s.first_ns as f64 / 1e9, s.last_ns as f64 / 1e9);
            for s in self.topics.iter().filter(|s| s.with_values > 0 && s.skipped.is_none()) {
                if s.last_ns < c.first_ns || s.first_ns > c.last_ns {
                    self.warnings.push(format!(
                        "{}: its times ({}) miss those of the clock topic `{}` ({}), so its columns are NaN; \
                         header stamps and log times on different clocks? `--time log` uses the log time throughout",
                        s.head,
                        span(s),
                        c.name,
                        span(c)
                    ));
                }
            }
        }
        for s in &self.topics {
            if let Some(why) = &s.skipped {
                self.warnings.push(format!("{}: {why}; skipped {} message(s)", s.head, s.messages));
            } else if s.messages > s.with_values && self.wanted_topic(&s.name) {
                let n = s.messages - s.with_values;
                self.warnings.push(format!(
                    "{}: {n} of {} message(s) had no numeric values and were left out",
                    s.head, s.messages
                ));
            }
            if !s.long_arrays.is_empty() {
                self.warnings.push(format!(
                    "{}: arrays longer than {} values are not columns: {}",
                    s.head,
                    super::cdr_walk::MAX_ARRAY_VALUES,
                    s.long_arrays.join(", ")
                ));
            }
        }
        Ok(())
    }

    fn wanted_topic(&self, name: &str) -> bool {
        self.wanted.is_empty() || self.wanted.iter().any(|w| w == name)
    }

    fn is_json_topic(&self, topic: usize) -> bool {
        self.channels.iter().any(|c| c.topic == topic && matches!(c.kind, Kind::Json))
    }

    /// `time`, then the message columns in first-seen order.
    pub fn columns(&self) -> &[String] {
        &self.columns
    }

    /// Skipped channels and topics with messages that gave no values.
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// The topic whose message times are the clock (none with `--resample-hz`).
    pub fn clock_topic(&self) -> Option<&str> {
        self.clock_topic.as_deref()
    }

    /// Rows read so far.
    pub fn rows_read(&self) -> u64 {
        self.rows_read
    }

    /// Messages with values read so far, per topic, in first-seen order (topics that gave
    /// none left out).
    pub fn messages_per_topic(&self) -> Vec<(String, u64)> {
        self.topics.iter().filter(|t| t.read > 0).map(|t| (t.name.clone(), t.read)).collect()
    }

    /// Reads the next row; `Ok(false)` at the end. A damaged file gives every row before
    /// the damage, then the error. Warnings found while reading are added to
    /// [`BagReader::warnings`] by the end.
    pub fn read_row(&mut self, row: &mut Vec<f64>) -> Result<bool, IoError> {
        loop {
            if let Some(mut r) = self.aligner.pop() {
                std::mem::swap(row, &mut r);
                self.aligner.recycle(r);
                self.rows_read += 1;
                return Ok(true);
            }
            if self.finished {
                return match self.stop.take() {
                    Some(e) => Err(e),
                    None => Ok(false),
                };
            }
            self.step()?;
        }
    }

    /// Reads one message into the aligner (through the reorder buffer).
    fn step(&mut self) -> Result<(), IoError> {
        let msg = match self.stream.next(&mut self.registry) {
            Ok(Some(m)) => m,
            Ok(None) => return self.end(None),
            Err(e) => {
                let e = IoError::Csv {
                    path: self.path.clone(),
                    msg: format!(
                        "stopped after message {} (log time {} s), the file is damaged from there: {e}",
                        self.messages,
                        self.last_log_ns as f64 / 1e9
                    ),
                };
                return self.end(Some(e));
            }
        };
        self.messages += 1;
        let Some((t, topic)) = self.decode(&msg, false)? else { return Ok(()) };
        if self.values.is_empty() {
            return Ok(());
        }
        self.topics[topic].read += 1;
        if self.lateness_ns == 0 && t >= self.newest_ns {
            self.newest_ns = t;
            return self.align(t, topic, None);
        }
        self.newest_ns = self.newest_ns.max(t);
        self.seq += 1;
        self.held.push(Reverse(Held { t_ns: t, seq: self.seq, topic, values: self.values.clone() }));
        let until = self.newest_ns.saturating_sub(self.lateness_ns);
        while self.held.peek().is_some_and(|h| h.0.t_ns <= until) {
            if let Some(Reverse(h)) = self.held.pop() {
                self.align(h.t_ns, h.topic, Some(&h.values))?;
            }
        }
        Ok(())
    }

    /// One message's values (`None`: those just decoded) into the aligner.
    fn align(&mut self, t_ns: i64, topic: usize, values: Option<&[(usize, f64)]>) -> Result<(), IoError> {
        let values = values.unwrap_or(&self.values);
        let mut again = false;
        for &(c, _) in values {
            if self.column_last_ns.len() <= c {
                self.column_last_ns.resize(c + 1, i64::MIN);
            }
            again |= self.column_last_ns[c] == t_ns;
            self.column_last_ns[c] = t_ns;
        }
        let stat = &mut self.topics[topic];
        if again {
            stat.same_time = (stat.same_time.0 + 1, if stat.same_time.0 == 0 { t_ns } else { stat.same_time.1 });
        }
        self.aligner.push(t_ns, topic, values).map_err(|e| IoError::Csv {
            path: self.path.clone(),
            msg: format!("topic `{}`, message at {} s: {e}", self.topics[topic].name, t_ns as f64 / 1e9),
        })
    }

    fn end(&mut self, error: Option<IoError>) -> Result<(), IoError> {
        while let Some(Reverse(h)) = self.held.pop() {
            self.align(h.t_ns, h.topic, Some(&h.values))?;
        }
        self.aligner.finish();
        if self.aligner.mode() != Align::None {
            for s in self.topics.iter().filter(|s| s.same_time.0 > 0) {
                self.warnings.push(format!(
                    "topic `{}`: {} message(s) give a column a second value at one time (the first at {} s); \
                     on one clock a time has one row, with the first value (`--align none` keeps every message)",
                    s.name,
                    s.same_time.0,
                    s.same_time.1 as f64 / 1e9
                ));
            }
        }
        self.finished = true;
        self.stop = error;
        Ok(())
    }
}

fn changed(path: &Path, name: &str) -> IoError {
    IoError::Csv {
        path: path.to_path_buf(),
        msg: format!("column `{name}` appeared on the second read (file changed while reading?)"),
    }
}
