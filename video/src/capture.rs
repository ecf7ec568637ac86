//! Frames from a user's GStreamer pipeline, copied once into shared memory.
//!
//! **The pipeline rule.** The user's description (`gst-launch-1.0` syntax) must end in an
//! `appsink` element: its last `!`-separated segment (outside quotes) starts with `appsink`.
//! Just before that segment this module inserts
//! `videoconvert ! videoscale add-borders=false ! capsfilter caps=video/x-raw,format=F,width=W,height=H,pixel-aspect-ratio=1/1`
//! with `F` = `RGB` (or `GRAY16_LE` for depth) and `W`×`H` the workflow's camera size. Both
//! converters run in passthrough (no copy, no work) when the user's pipeline already delivers
//! that format and size; otherwise they convert and scale (stretching, never letterboxing, when
//! the aspect ratio differs). The appsink's own `caps` are overwritten with the same caps, and
//! it keeps only the newest buffer (`max-buffers=1 drop=true`): a consumer that falls behind
//! gets the freshest frame, never a backlog. Its `sync` property is the user's: a live source
//! (camera, `udpsrc`, `videotestsrc is-live=true`) wants `sync=false` (a buffer is handed over
//! as soon as it exists); a file wants the default `sync=true` (played at its own rate).
//!
//! **Capture time.** A buffer's capture time on the pipeline clock is
//! `base_time + running_time(PTS)` (the PTS mapped through the sample's segment). The pipeline
//! is made to use GStreamer's system clock, whose default `clock-type` is `monotonic`: it reads
//! `clock_gettime(CLOCK_MONOTONIC)`, the clock of [`aeris_runtime::clock::monotonic_ns`], so the
//! pipeline clock time *is* our time (checked when the capture is built, and by a test that a
//! reading of the system clock falls between two readings of ours). Were the system clock set
//! to another type, the offset between the two clocks is measured for every frame instead. A
//! live source stamps each buffer with the running time at which it was captured (a camera's
//! driver time, `udpsrc`'s arrival time of the packet); a buffer without PTS (rare) gets the
//! time it was pulled, and says so ([`CapturedFrame::pts_mapped`]).
//!
//! **Copies.** [`CapturedFrame::copy_to`] maps the buffer for reading and copies it once into
//! the caller's slice (row by row when GStreamer pads rows to a stride); nothing else copies
//! pixels. GStreamer itself allocates its sample and buffer structures per frame; this module
//! adds no heap allocation per frame.
//!
//! **Events.** [`Capture::poll_event`] turns the pipeline's bus into [`CaptureEvent`]s: an
//! error (GStreamer's element, message and debug text), the end of the stream, a stall (no
//! buffer for the configured time) and the resumption after one.

use crate::InitError;
use aeris_runtime::clock::monotonic_ns;
use core::time::Duration;
use gstreamer as gst;
use gstreamer::prelude::*;
use gstreamer_app as gst_app;
use gstreamer_video as gst_video;

/// The pixel format a capture delivers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PixelFormat {
    /// 8-bit RGB, 3 bytes a pixel (`camera/rgb`).
    Rgb8,
    /// 16-bit little-endian grey, millimetres of depth (`camera/depth`).
    Gray16Le,
}

impl PixelFormat {
    /// Bytes per pixel.
    pub fn bytes_per_pixel(self) -> usize {
        match self {
            PixelFormat::Rgb8 => 3,
            PixelFormat::Gray16Le => 2,
        }
    }

    /// GStreamer's name of the format.
    pub fn gst_name(self) -> &'static str {
        match self {
            PixelFormat::Rgb8 => "RGB",
            PixelFormat::Gray16Le => "GRAY16_LE",
        }
    }
}

/// What to capture.
#[derive(Debug, Clone, PartialEq)]
pub struct CaptureConfig {
    /// The user's pipeline description, ending in an `appsink` (see the module docs).
    pub pipeline: String,
    /// The format every frame is converted to.
    pub format: PixelFormat,
    /// Frame width (pixels).
    pub width: u32,
    /// Frame height (pixels).
    pub height: u32,
    /// No buffer for this long is a stall ([`CaptureEvent::Stalled`]).
    pub stall: Duration,
}

/// Largest accepted frame side (pixels).
pub const MAX_SIDE: u32 = 8192;

/// Names of the elements this module inserts (so they can be found again).
const CAPS_NAME: &str = "aeris_caps";

/// Why a capture could not be built.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    /// GStreamer could not be initialised.
    #[error(transparent)]
    Init(#[from] InitError),
    /// The frame size is zero or larger than [`MAX_SIDE`].
    #[error("frame size {width}x{height} is outside 1..={MAX_SIDE} pixels a side")]
    Size {
        /// Width asked for.
        width: u32,
        /// Height asked for.
        height: u32,
    },
    /// The description's last element is not an `appsink`.
    #[error("the pipeline must end in an `appsink` element, not `{last}`")]
    NoAppSink {
        /// The last segment of the description.
        last: String,
    },
    /// GStreamer could not parse the description (its message names the element or
    /// property).
    #[error("GStreamer cannot parse the pipeline")]
    Parse(#[source] gst::glib::Error),
    /// The parsed description is not a linked pipeline ending in an appsink.
    #[error("the pipeline does not end in an `appsink` fed by its other elements")]
    Unlinked,
}

/// What GStreamer said about a failure: the element, its message and its debug text.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GstText {
    /// Path of the element that posted the message (`/GstPipeline:pipeline0/GstUDPSrc:udpsrc0`).
    pub element: String,
    /// GStreamer's error message.
    pub message: String,
    /// GStreamer's debug text (source file, function, details), when given.
    pub debug: Option<String>,
}

impl core::fmt::Display for GstText {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        // GStreamer's debug text usually names the element itself: name it once
        match &self.debug {
            Some(d) if d.contains(&self.element) => write!(f, "{} ({d})", self.message),
            Some(d) => write!(f, "{}: {} ({d})", self.element, self.message),
            None => write!(f, "{}: {}", self.element, self.message),
        }
    }
}

impl GstText {
    pub(crate) fn from_error(e: &gst::message::Error) -> Self {
        GstText {
            element: e
                .src()
                .map(|s| s.path_string().to_string())
                .unwrap_or_else(|| "pipeline".into()),
            message: e.error().to_string(),
            debug: e.debug().map(|d| d.to_string()),
        }
    }
}

/// Why a capture did not start.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    /// GStreamer refused to bring the pipeline up (a device or port that cannot be opened, a
    /// missing file), with its own words.
    #[error("the pipeline did not start: {0}")]
    Refused(GstText),
    /// GStreamer refused to bring the pipeline up and posted no error message.
    #[error("the pipeline did not start and GStreamer gave no reason")]
    NoReason,
    /// The description, parsed once already, could not be parsed again for a restart (a
    /// plugin removed meanwhile).
    #[error("the pipeline could not be built again for a restart")]
    Rebuild(#[source] BuildError),
}

/// Why a frame could not be copied out.
#[derive(Debug, thiserror::Error)]
pub enum CopyError {
    /// The sample carries no buffer.
    #[error("the sample carries no buffer")]
    NoBuffer,
    /// The buffer could not be mapped for reading.
    #[error("the buffer cannot be mapped for reading")]
    Map,
    /// The destination is not exactly one frame long.
    #[error("the destination holds {got} bytes, a frame {want}")]
    Destination {
        /// Destination length.
        got: usize,
        /// Frame length.
        want: usize,
    },
    /// The buffer is shorter than its layout says (a broken upstream element).
    #[error("the buffer holds {got} bytes, its {rows} rows of stride {stride} need more")]
    Short {
        /// Buffer length.
        got: usize,
        /// Rows of the frame.
        rows: usize,
        /// Bytes per row in the buffer.
        stride: usize,
    },
}

/// Something the pipeline reported, for the caller to log and act on.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CaptureEvent {
    /// An element failed; the pipeline has stopped streaming and must be restarted.
    Error(GstText),
    /// The stream ended (a file played out, a source that stopped): restart to go on.
    Eos,
    /// No buffer arrived for the configured stall time (a cut link, an unplugged camera).
    Stalled {
        /// Milliseconds since the last buffer (or since the start).
        silent_ms: u64,
    },
    /// Buffers arrive again after a stall.
    Resumed {
        /// Milliseconds the stall lasted.
        after_ms: u64,
    },
}

/// A running (or stopped) capture pipeline.
pub struct Capture {
    /// The description as parsed (the converters inserted), parsed again for every restart.
    description: String,
    pipeline: gst::Pipeline,
    sink: gst_app::AppSink,
    bus: gst::Bus,
    clock: gst::Clock,
    clock_is_monotonic: bool,
    format: PixelFormat,
    width: u32,
    height: u32,
    stall_ns: u64,
    /// Whether the pipeline has been brought up before (a restart then builds a new one).
    started: bool,
    running: bool,
    last_frame_ns: u64,
    stalled_since: Option<u64>,
    resumed_after: Option<u64>,
}

impl core::fmt::Debug for Capture {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Capture")
            .field("pipeline", &self.pipeline.name())
            .field("format", &self.format)
            .field("size", &(self.width, self.height))
            .field("running", &self.running)
            .finish()
    }
}

/// Split `description` at its last `!` outside quotes: (head, last segment).
fn split_last(description: &str) -> (&str, &str) {
    let mut quote: Option<char> = None;
    let mut cut = None;
    let mut escaped = false;
    for (i, c) in description.char_indices() {
        match (quote, c) {
            _ if escaped => escaped = false,
            (_, '\\') => escaped = true,
            (None, '"' | '\'') => quote = Some(c),
            (Some(q), c) if c == q => quote = None,
            (None, '!') => cut = Some(i),
            _ => {}
        }
    }
    match cut {
        Some(i) => (&description[..i], &description[i + 1..]),
        None => ("", description),
    }
}

/// The caps every frame is forced to.
fn forced_caps(format: PixelFormat, width: u32, height: u32) -> String {
    format!(
        "video/x-raw,format={},width={width},height={height},pixel-aspect-ratio=1/1",
        format.gst_name()
    )
}

/// The description with the converters inserted before the appsink (see the module docs).
pub fn forced_description(
    description: &str,
    format: PixelFormat,
    width: u32,
    height: u32,
) -> Result<String, BuildError> {
    let (head, last) = split_last(description);
    let last = last.trim();
    let element = last.split_whitespace().next().unwrap_or("");
    if element != "appsink" {
        return Err(BuildError::NoAppSink {
            last: last.to_string(),
        });
    }
    let caps = forced_caps(format, width, height);
    let head = head.trim();
    let head = if head.is_empty() {
        String::new()
    } else {
        format!("{head} ! ")
    };
    Ok(format!(
        "{head}videoconvert name=aeris_convert ! videoscale name=aeris_scale add-borders=false \
         ! capsfilter name={CAPS_NAME} caps=\"{caps}\" ! {last}"
    ))
}

/// A parsed pipeline: the pipeline, its appsink (caps forced) and its bus.
struct Built {
    pipeline: gst::Pipeline,
    sink: gst_app::AppSink,
    bus: gst::Bus,
}

/// Parse `description` (the converters already inserted) into a pipeline that runs on `clock`,
/// its appsink accepting exactly `format` at `width`×`height`.
fn build(
    description: &str,
    format: PixelFormat,
    width: u32,
    height: u32,
    clock: &gst::Clock,
) -> Result<Built, BuildError> {
    let element = gst::parse::launch(description).map_err(BuildError::Parse)?;
    let pipeline = element
        .downcast::<gst::Pipeline>()
        .map_err(|_| BuildError::Unlinked)?;
    let sink = pipeline
        .by_name(CAPS_NAME)
        .and_then(|c| c.static_pad("src"))
        .and_then(|p| p.peer())
        .and_then(|p| p.parent_element())
        .and_then(|e| e.downcast::<gst_app::AppSink>().ok())
        .ok_or(BuildError::Unlinked)?;
    let caps = gst::Caps::builder("video/x-raw")
        .field("format", format.gst_name())
        .field("width", width as i32)
        .field("height", height as i32)
        .field("pixel-aspect-ratio", gst::Fraction::new(1, 1))
        .build();
    sink.set_caps(Some(&caps));
    sink.set_max_buffers(1);
    sink.set_drop(true);
    pipeline.use_clock(Some(clock));
    let bus = pipeline.bus().ok_or(BuildError::Unlinked)?;
    Ok(Built {
        pipeline,
        sink,
        bus,
    })
}

impl Capture {
    /// Parse and set up `config.pipeline` (not started: see [`Capture::start`]).
    pub fn new(config: &CaptureConfig) -> Result<Self, BuildError> {
        crate::init()?;
        let (w, h) = (config.width, config.height);
        if !(1..=MAX_SIDE).contains(&w) || !(1..=MAX_SIDE).contains(&h) {
            return Err(BuildError::Size {
                width: w,
                height: h,
            });
        }
        let description = forced_description(&config.pipeline, config.format, w, h)?;
        let clock = gst::SystemClock::obtain();
        let clock_is_monotonic = clock
            .has_property_with_type("clock-type", gst::ClockType::static_type())
            && clock.property::<gst::ClockType>("clock-type") == gst::ClockType::Monotonic;
        let Built {
            pipeline,
            sink,
            bus,
        } = build(&description, config.format, w, h, &clock)?;
        Ok(Capture {
            description,
            pipeline,
            sink,
            bus,
            clock,
            clock_is_monotonic,
            format: config.format,
            width: w,
            height: h,
            stall_ns: u64::try_from(config.stall.as_nanos()).unwrap_or(u64::MAX),
            started: false,
            running: false,
            last_frame_ns: 0,
            stalled_since: None,
            resumed_after: None,
        })
    }

    /// Bytes of one frame (what [`CapturedFrame::copy_to`] fills).
    pub fn frame_len(&self) -> usize {
        self.width as usize * self.height as usize * self.format.bytes_per_pixel()
    }

    /// Whether the pipeline clock reads CLOCK_MONOTONIC itself (the default; see the module
    /// docs).
    pub fn clock_is_monotonic(&self) -> bool {
        self.clock_is_monotonic
    }

    /// Whether the pipeline was started and not stopped since.
    pub fn is_running(&self) -> bool {
        self.running
    }

    /// Bring the pipeline to PLAYING. A failure that GStreamer reports at once (a device, port
    /// or file that cannot be opened) is an error with its text; one it reports later comes as
    /// a [`CaptureEvent::Error`].
    ///
    /// Every start after the first runs a pipeline parsed anew from the description: elements
    /// that add their pads once data flows (`decodebin`, `rtspsrc`, demuxers) are linked by
    /// the parser only once, so the stopped pipeline cannot be brought up again (its decoder
    /// would feed nothing: "streaming stopped, reason not-linked").
    pub fn start(&mut self) -> Result<(), StartError> {
        if self.started {
            let _ = self.pipeline.set_state(gst::State::Null);
            let built = build(
                &self.description,
                self.format,
                self.width,
                self.height,
                &self.clock,
            )
            .map_err(StartError::Rebuild)?;
            self.pipeline = built.pipeline;
            self.sink = built.sink;
            self.bus = built.bus;
        }
        self.started = true;
        if self.pipeline.set_state(gst::State::Playing).is_err() {
            let text = self
                .bus
                .pop_filtered(&[gst::MessageType::Error])
                .and_then(|m| match m.view() {
                    gst::MessageView::Error(e) => Some(GstText::from_error(e)),
                    _ => None,
                });
            let _ = self.pipeline.set_state(gst::State::Null);
            self.running = false;
            return Err(text.map_or(StartError::NoReason, StartError::Refused));
        }
        self.running = true;
        self.last_frame_ns = monotonic_ns();
        self.stalled_since = None;
        self.resumed_after = None;
        Ok(())
    }

    /// Stop the pipeline (to NULL: devices and ports are released).
    pub fn stop(&mut self) {
        let _ = self.pipeline.set_state(gst::State::Null);
        self.running = false;
    }

    /// The next frame, waiting at most `timeout` for one; `None` when none came (or the
    /// capture is not running: then it returns at once).
    pub fn pull(&mut self, timeout: Duration) -> Option<CapturedFrame> {
        if !self.running {
            return None;
        }
        let t =
            gst::ClockTime::from_nseconds(u64::try_from(timeout.as_nanos()).unwrap_or(u64::MAX));
        let sample = self.sink.try_pull_sample(t)?;
        let arrival_ns = monotonic_ns();
        if let Some(since) = self.stalled_since.take() {
            self.resumed_after = Some(arrival_ns.saturating_sub(since) / 1_000_000);
        }
        self.last_frame_ns = arrival_ns;
        let mapped = self.capture_time(&sample);
        Some(CapturedFrame {
            capture_ns: mapped.unwrap_or(arrival_ns),
            pts_mapped: mapped.is_some(),
            arrival_ns,
            width: self.width,
            height: self.height,
            format: self.format,
            sample,
        })
    }

    /// `base_time + running_time(PTS)` on the pipeline clock, as CLOCK_MONOTONIC ns.
    fn capture_time(&self, sample: &gst::Sample) -> Option<u64> {
        let pts = sample.buffer()?.pts()?;
        let segment = sample.segment()?.downcast_ref::<gst::ClockTime>()?;
        let running = segment.to_running_time(pts)?;
        let base = self.pipeline.base_time()?;
        let clock_ns = base.nseconds().checked_add(running.nseconds())?;
        if self.clock_is_monotonic {
            return Some(clock_ns);
        }
        let now_clock = self.clock.time().nseconds();
        let now = monotonic_ns();
        let t = i128::from(clock_ns) + i128::from(now) - i128::from(now_clock);
        u64::try_from(t.max(0)).ok()
    }

    /// The next event, if any: bus errors and end of stream first, then a stall or the end
    /// of one. Never blocks.
    pub fn poll_event(&mut self) -> Option<CaptureEvent> {
        if let Some(after_ms) = self.resumed_after.take() {
            return Some(CaptureEvent::Resumed { after_ms });
        }
        while let Some(msg) = self
            .bus
            .pop_filtered(&[gst::MessageType::Error, gst::MessageType::Eos])
        {
            match msg.view() {
                gst::MessageView::Error(e) => {
                    return Some(CaptureEvent::Error(GstText::from_error(e)));
                }
                gst::MessageView::Eos(_) => return Some(CaptureEvent::Eos),
                _ => {}
            }
        }
        if self.running && self.stalled_since.is_none() {
            let now = monotonic_ns();
            let silent = now.saturating_sub(self.last_frame_ns);
            if silent >= self.stall_ns {
                self.stalled_since = Some(self.last_frame_ns);
                return Some(CaptureEvent::Stalled {
                    silent_ms: silent / 1_000_000,
                });
            }
        }
        None
    }
}

impl Drop for Capture {
    fn drop(&mut self) {
        let _ = self.pipeline.set_state(gst::State::Null);
    }
}

/// One pulled frame, still in GStreamer's buffer.
pub struct CapturedFrame {
    sample: gst::Sample,
    /// Capture time, CLOCK_MONOTONIC ns (see the module docs).
    pub capture_ns: u64,
    /// `true` when `capture_ns` comes from the buffer's PTS; `false` when the buffer had no
    /// usable PTS and `capture_ns` is the time it was pulled.
    pub pts_mapped: bool,
    /// When the frame was pulled, CLOCK_MONOTONIC ns.
    pub arrival_ns: u64,
    width: u32,
    height: u32,
    format: PixelFormat,
}

impl core::fmt::Debug for CapturedFrame {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("CapturedFrame")
            .field("capture_ns", &self.capture_ns)
            .field("pts_mapped", &self.pts_mapped)
            .field("arrival_ns", &self.arrival_ns)
            .finish()
    }
}

impl CapturedFrame {
    /// Where the rows lie in the buffer: (offset, stride, buffer length), checked against the
    /// frame size.
    fn layout(&self) -> Result<(usize, usize), CopyError> {
        let row = self.width as usize * self.format.bytes_per_pixel();
        let rows = self.height as usize;
        let buffer = self.sample.buffer().ok_or(CopyError::NoBuffer)?;
        let (offset, stride) = match buffer.meta::<gst_video::VideoMeta>() {
            Some(m) => (
                m.offset().first().copied().unwrap_or(0),
                m.stride()
                    .first()
                    .and_then(|s| usize::try_from(*s).ok())
                    .unwrap_or(0),
            ),
            // GStreamer's default layout: rows start on 4-byte boundaries
            None => (0, row.div_ceil(4) * 4),
        };
        let got = buffer.size();
        if stride < row || got < offset + stride * (rows - 1) + row {
            return Err(CopyError::Short { got, rows, stride });
        }
        Ok((offset, stride))
    }

    /// Check that the buffer holds a whole frame (what [`CapturedFrame::copy_to`] needs),
    /// before a destination is loaned for it.
    pub fn check(&self) -> Result<(), CopyError> {
        self.layout().map(|_| ())
    }

    /// Copy the frame's pixels, tightly packed rows, into `dst` (exactly one frame long):
    /// the one copy of the frame.
    pub fn copy_to(&self, dst: &mut [u8]) -> Result<(), CopyError> {
        let row = self.width as usize * self.format.bytes_per_pixel();
        let want = row * self.height as usize;
        if dst.len() != want {
            return Err(CopyError::Destination {
                got: dst.len(),
                want,
            });
        }
        let (offset, stride) = self.layout()?;
        let buffer = self.sample.buffer().ok_or(CopyError::NoBuffer)?;
        let map = buffer.map_readable().map_err(|_| CopyError::Map)?;
        let src = map.as_slice();
        let short = || CopyError::Short {
            got: src.len(),
            rows: self.height as usize,
            stride,
        };
        if stride == row {
            dst.copy_from_slice(src.get(offset..offset + want).ok_or_else(short)?);
        } else {
            for (y, out) in dst.chunks_exact_mut(row).enumerate() {
                let start = offset + y * stride;
                out.copy_from_slice(src.get(start..start + row).ok_or_else(short)?);
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_converters_go_before_the_last_appsink_outside_quotes() {
        let d = forced_description(
            "udpsrc caps=\"application/x-rtp, a=b ! c\" ! rtph264depay ! appsink sync=false",
            PixelFormat::Rgb8,
            320,
            240,
        )
        .unwrap();
        assert!(d.starts_with(
            "udpsrc caps=\"application/x-rtp, a=b ! c\" ! rtph264depay ! videoconvert"
        ));
        assert!(d.ends_with(
            "format=RGB,width=320,height=240,pixel-aspect-ratio=1/1\" ! appsink sync=false"
        ));
        assert!(matches!(
            forced_description("videotestsrc ! fakesink", PixelFormat::Rgb8, 2, 2),
            Err(BuildError::NoAppSink { last }) if last == "fakesink"
        ));
        assert!(matches!(
            forced_description("videotestsrc ! appsinkx", PixelFormat::Rgb8, 2, 2),
            Err(BuildError::NoAppSink { .. })
        ));
    }

    /// GStreamer's system clock reads CLOCK_MONOTONIC, the clock of `monotonic_ns`: a reading
    /// of it lies between two readings of ours (an ordering, not a timing threshold).
    #[test]
    fn the_system_clock_is_our_monotonic_clock() {
        crate::init().unwrap();
        let clock = gst::SystemClock::obtain();
        assert_eq!(
            clock.property::<gst::ClockType>("clock-type"),
            gst::ClockType::Monotonic
        );
        for _ in 0..100 {
            let before = monotonic_ns();
            let t = clock.time().nseconds();
            let after = monotonic_ns();
            assert!(before <= t && t <= after, "{before} <= {t} <= {after}");
        }
    }
}
