//! RGB frames into H.264: an MP4 file or an RTP/UDP stream.
//!
//! The pipeline, built element by element (no description string, so a path or host needs
//! no quoting):
//!
//! ```text
//! appsrc (video/x-raw,format=RGB,W×H,fps) ! videoconvert ! video/x-raw,format=I420
//!   ! x264enc tune=zerolatency speed-preset=fast key-int-max=fps   (else openh264enc)
//!   ! h264parse ! mp4mux ! filesink location=FILE                      (VideoSink::Mp4)
//!   ! h264parse ! rtph264pay config-interval=1 pt=96 ! udpsink host port (VideoSink::Rtp)
//! ```
//!
//! I420 keeps the stream in the profiles every decoder plays (RGB input would otherwise make
//! x264 pick High 4:4:4). A key frame every second and the parameter sets sent with every key
//! frame (`config-interval=1`) let a receiver that joins late, or whose link was cut, decode
//! again within a second.
//!
//! Timing: for a file, frame `n` gets PTS `n / fps` (the file plays at the camera rate however
//! long rendering took); for a stream, `appsrc` is live and stamps each frame with the running
//! time at which it is pushed, and `udpsink` sends at once (`sync=false`): the caller paces
//! the frames in real time. [`Encoder::finish`] sends end-of-stream and, for a file, waits
//! until `mp4mux` has written its index: an MP4 that was not finished does not play.

use crate::InitError;
use core::time::Duration;
use gstreamer as gst;
use gstreamer::prelude::*;
use gstreamer_app as gst_app;
use gstreamer_video as gst_video;
use std::path::PathBuf;

/// Where the encoded video goes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum VideoSink {
    /// An MP4 file (H.264).
    Mp4(PathBuf),
    /// RTP (H.264, payload type 96) over UDP to `host:port`.
    Rtp {
        /// Host name or address.
        host: String,
        /// UDP port.
        port: u16,
    },
}

/// What to encode.
#[derive(Debug, Clone, PartialEq)]
pub struct EncoderConfig {
    /// Frame width (pixels).
    pub width: u32,
    /// Frame height (pixels).
    pub height: u32,
    /// Frames per second (whole frames).
    pub fps: u32,
    /// Where the video goes.
    pub sink: VideoSink,
}

/// Why an encoder could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum EncoderStartError {
    /// GStreamer could not be initialised.
    #[error(transparent)]
    Init(#[from] InitError),
    /// Width, height or rate is zero or too large.
    #[error("{width}x{height} at {fps} fps is not an encodable video")]
    Size {
        /// Width.
        width: u32,
        /// Height.
        height: u32,
        /// Frames per second.
        fps: u32,
    },
    /// An element this pipeline needs is not installed.
    #[error("GStreamer element `{0}` is not installed (see scripts/setup-build-deps.sh)")]
    Missing(&'static str),
    /// Neither H.264 encoder is installed.
    #[error("no H.264 encoder: neither `x264enc` nor `openh264enc` is installed")]
    NoEncoder,
    /// The elements would not link.
    #[error("the encoder's elements do not link")]
    Link(#[source] gst::glib::BoolError),
    /// GStreamer refused to start the pipeline (an unwritable file, an unknown host).
    #[error("the encoder did not start: {0}")]
    Refused(crate::capture::GstText),
}

/// Why a frame could not be pushed.
#[derive(Debug, thiserror::Error)]
pub enum PushError {
    /// GStreamer could not allocate the frame's buffer.
    #[error("cannot allocate a {0}-byte frame buffer")]
    Alloc(usize),
    /// The pipeline failed (its element's error text).
    #[error("the encoder failed: {0}")]
    Failed(crate::capture::GstText),
    /// The pipeline does not take buffers any more (flushing or ended).
    #[error("the encoder refused the frame ({0:?})")]
    Flow(gst::FlowError),
}

/// Why an encoder did not finish cleanly.
#[derive(Debug, thiserror::Error)]
pub enum FinishError {
    /// The pipeline failed while draining (its element's error text).
    #[error("the encoder failed while finishing: {0}")]
    Failed(crate::capture::GstText),
    /// The end of stream did not come through in time.
    #[error("the encoder did not finish within {0:?}")]
    Timeout(Duration),
}

/// An H.264 encoder fed with RGB frames.
pub struct Encoder {
    pipeline: gst::Pipeline,
    src: gst_app::AppSrc,
    bus: gst::Bus,
    encoder: &'static str,
    live: bool,
    frames: u64,
    frame_ns: u64,
    width: u32,
    height: u32,
}

impl core::fmt::Debug for Encoder {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Encoder")
            .field("encoder", &self.encoder)
            .field("live", &self.live)
            .field("frames", &self.frames)
            .finish()
    }
}

fn make(factory: &'static str) -> Result<gst::Element, EncoderStartError> {
    gst::ElementFactory::make(factory)
        .build()
        .map_err(|_| EncoderStartError::Missing(factory))
}

/// The first error message on `bus`, if any.
fn bus_error(bus: &gst::Bus) -> Option<crate::capture::GstText> {
    let msg = bus.pop_filtered(&[gst::MessageType::Error])?;
    match msg.view() {
        gst::MessageView::Error(e) => Some(crate::capture::GstText::from_error(e)),
        _ => None,
    }
}

impl Encoder {
    /// Build and start the encoder.
    pub fn new(config: &EncoderConfig) -> Result<Self, EncoderStartError> {
        crate::init()?;
        let (w, h, fps) = (config.width, config.height, config.fps);
        let max = crate::capture::MAX_SIDE;
        if !(1..=max).contains(&w) || !(1..=max).contains(&h) || !(1..=1000).contains(&fps) {
            return Err(EncoderStartError::Size {
                width: w,
                height: h,
                fps,
            });
        }
        let live = matches!(config.sink, VideoSink::Rtp { .. });
        let caps = gst::Caps::builder("video/x-raw")
            .field("format", "RGB")
            .field("width", w as i32)
            .field("height", h as i32)
            .field("framerate", gst::Fraction::new(fps as i32, 1))
            .field("pixel-aspect-ratio", gst::Fraction::new(1, 1))
            .build();
        let src = gst_app::AppSrc::builder()
            .caps(&caps)
            .format(gst::Format::Time)
            .is_live(live)
            .do_timestamp(live)
            .block(!live)
            .max_bytes(w as u64 * h as u64 * 3 * 4)
            .build();
        let convert = make("videoconvert")?;
        let i420 = gst::ElementFactory::make("capsfilter")
            .property(
                "caps",
                gst::Caps::builder("video/x-raw")
                    .field("format", "I420")
                    .build(),
            )
            .build()
            .map_err(|_| EncoderStartError::Missing("capsfilter"))?;
        let (encoder_name, encoder) = if let Ok(e) = gst::ElementFactory::make("x264enc").build() {
            e.set_property_from_str("tune", "zerolatency");
            e.set_property_from_str("speed-preset", "fast");
            e.set_property("key-int-max", fps);
            ("x264enc", e)
        } else if let Ok(e) = gst::ElementFactory::make("openh264enc").build() {
            if e.has_property("gop-size") {
                e.set_property("gop-size", fps);
            }
            ("openh264enc", e)
        } else {
            return Err(EncoderStartError::NoEncoder);
        };
        let parse = make("h264parse")?;
        let mut chain = vec![
            src.clone().upcast::<gst::Element>(),
            convert,
            i420,
            encoder,
            parse,
        ];
        match &config.sink {
            VideoSink::Mp4(path) => {
                chain.push(make("mp4mux")?);
                let sink = make("filesink")?;
                sink.set_property("location", path.to_string_lossy().as_ref());
                chain.push(sink);
            }
            VideoSink::Rtp { host, port } => {
                let pay = make("rtph264pay")?;
                pay.set_property("config-interval", 1i32);
                pay.set_property("pt", 96u32);
                chain.push(pay);
                let sink = make("udpsink")?;
                sink.set_property("host", host.as_str());
                sink.set_property("port", i32::from(*port));
                sink.set_property("sync", false);
                sink.set_property("async", false);
                chain.push(sink);
            }
        }
        let pipeline = gst::Pipeline::new();
        pipeline.add_many(&chain).map_err(EncoderStartError::Link)?;
        gst::Element::link_many(&chain).map_err(EncoderStartError::Link)?;
        let bus = pipeline.bus().ok_or(EncoderStartError::Missing("bus"))?;
        if pipeline.set_state(gst::State::Playing).is_err() {
            let text = bus_error(&bus);
            let _ = pipeline.set_state(gst::State::Null);
            return Err(EncoderStartError::Refused(text.unwrap_or(
                crate::capture::GstText {
                    element: "pipeline".into(),
                    message: "refused to start".into(),
                    debug: None,
                },
            )));
        }
        Ok(Encoder {
            pipeline,
            src,
            bus,
            encoder: encoder_name,
            live,
            frames: 0,
            frame_ns: 1_000_000_000 / u64::from(fps),
            width: w,
            height: h,
        })
    }

    /// The H.264 encoder in use: `x264enc` or `openh264enc`.
    pub fn encoder_name(&self) -> &'static str {
        self.encoder
    }

    /// Frames pushed so far.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// Bytes of one RGB frame.
    pub fn frame_len(&self) -> usize {
        self.width as usize * self.height as usize * 3
    }

    /// Push one frame: `fill` writes its tightly packed RGB rows straight into the frame's
    /// GStreamer buffer (no other copy).
    pub fn push_with(&mut self, fill: impl FnOnce(&mut [u8])) -> Result<(), PushError> {
        if let Some(text) = bus_error(&self.bus) {
            return Err(PushError::Failed(text));
        }
        let len = self.frame_len();
        let mut buffer = gst::Buffer::with_size(len).map_err(|_| PushError::Alloc(len))?;
        {
            let b = buffer.get_mut().ok_or(PushError::Alloc(len))?;
            if !self.live {
                b.set_pts(gst::ClockTime::from_nseconds(self.frames * self.frame_ns));
                b.set_duration(gst::ClockTime::from_nseconds(self.frame_ns));
            }
            // tight rows: say so, GStreamer's default RGB stride is rounded up to 4 bytes
            let stride = (self.width * 3) as i32;
            gst_video::VideoMeta::add_full(
                b,
                gst_video::VideoFrameFlags::empty(),
                gst_video::VideoFormat::Rgb,
                self.width,
                self.height,
                &[0],
                &[stride],
            )
            .map_err(|_| PushError::Alloc(len))?;
            let mut map = b.map_writable().map_err(|_| PushError::Alloc(len))?;
            fill(map.as_mut_slice());
        }
        self.src.push_buffer(buffer).map_err(PushError::Flow)?;
        self.frames += 1;
        Ok(())
    }

    /// Send end-of-stream and wait (at most `timeout`) until it has gone through: for an MP4,
    /// until the file is complete.
    pub fn finish(self, timeout: Duration) -> Result<(), FinishError> {
        let _ = self.src.end_of_stream();
        let t =
            gst::ClockTime::from_nseconds(u64::try_from(timeout.as_nanos()).unwrap_or(u64::MAX));
        let result = match self
            .bus
            .timed_pop_filtered(t, &[gst::MessageType::Eos, gst::MessageType::Error])
        {
            Some(msg) => match msg.view() {
                gst::MessageView::Error(e) => {
                    Err(FinishError::Failed(crate::capture::GstText::from_error(e)))
                }
                _ => Ok(()),
            },
            None => Err(FinishError::Timeout(timeout)),
        };
        let _ = self.pipeline.set_state(gst::State::Null);
        result
    }
}

impl Drop for Encoder {
    fn drop(&mut self) {
        let _ = self.pipeline.set_state(gst::State::Null);
    }
}
