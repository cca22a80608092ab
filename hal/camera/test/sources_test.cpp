#include <gtest/gtest.h>

#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include "jpeg_test_images.hpp"
#include "tcpest/hal/camera/file_sources.hpp"
#include "tcpest/hal/camera/pixel_formats.hpp"
#include "tcpest/hal/camera/sim_camera.hpp"
#include "tcpest/hal/camera/v4l2_source.hpp"
#include "tcpest/test/alloc_counter.hpp"

namespace tcpest {
namespace hal {
namespace {

std::string temp_dir(const char* tag) {
  std::string pattern = std::string(::testing::TempDir()) + "tcpest_" + tag + "_XXXXXX";
  std::vector<char> buf(pattern.begin(), pattern.end());
  buf.push_back('\0');
  const char* made = ::mkdtemp(buf.data());
  return made != nullptr ? std::string(made) : std::string();
}

void write_bytes(const std::string& path, const std::vector<std::uint8_t>& bytes) {
  std::ofstream f(path, std::ios::binary);
  f.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

struct Image {
  std::vector<std::uint8_t> bytes;
  MutableImageView view;
  Image(int w, int h) : bytes(static_cast<std::size_t>(w * h * 3)) {
    view = MutableImageView{bytes.data(), w, h, static_cast<std::size_t>(w) * 3U};
  }
};

// Verifies: REQ-HAL-002
TEST(Y4mHeader, ParsesWhatFfmpegWrites) {
  const char line[] = "YUV4MPEG2 W720 H576 F25:1 Ip A64:45 C420jpeg XYSCSS=420JPEG";
  const auto h = parse_y4m_header(line, sizeof line - 1U);
  ASSERT_TRUE(h.ok());
  EXPECT_EQ(h.value().width, 720);
  EXPECT_EQ(h.value().height, 576);
  EXPECT_EQ(h.value().rate_num, 25);
  EXPECT_EQ(h.value().rate_den, 1);
  EXPECT_EQ(h.value().layout, ChromaLayout::k420);
  EXPECT_EQ(h.value().range, YuvRange::kLimited);
  const char full[] = "YUV4MPEG2 W64 H48 F30000:1001 C444 XCOLORRANGE=FULL";
  const auto f = parse_y4m_header(full, sizeof full - 1U);
  ASSERT_TRUE(f.ok());
  EXPECT_EQ(f.value().layout, ChromaLayout::k444);
  EXPECT_EQ(f.value().range, YuvRange::kFull);
}

// Verifies: REQ-HAL-002
TEST(Y4mHeader, RefusesBadHeaders) {
  const char* bad[] = {"YUV4MPEG W720 H576", "YUV4MPEG2 W0 H576", "YUV4MPEG2 W720", "YUV4MPEG2 Wabc H5",
                       "YUV4MPEG2 W720 H576 F25:0", "YUV4MPEG2 W720 H576 C411", "YUV4MPEG2 W99999 H576"};
  for (const char* line : bad) {
    EXPECT_FALSE(parse_y4m_header(line, std::strlen(line)).ok()) << line;
  }
}

// Verifies: REQ-HAL-002
TEST(PixelFormats, Yuv420RoundTripIsClose) {
  const int w = 33;
  const int h = 17;
  const auto rgb = testing::make_pattern(w, h, 1);
  const ImageView in{rgb.data(), w, h, static_cast<std::size_t>(w) * 3U};
  std::vector<std::uint8_t> yuv(planar_frame_bytes(w, h, ChromaLayout::k420));
  rgb_to_planar_yuv420(in, YuvRange::kFull, yuv.data());
  Image out(w, h);
  planar_yuv_to_rgb(yuv.data(), w, h, ChromaLayout::k420, YuvRange::kFull, out.view);
  double sum = 0.0;
  for (std::size_t i = 0; i < rgb.size(); ++i) {
    sum += std::abs(static_cast<int>(rgb[i]) - static_cast<int>(out.bytes[i]));
  }
  EXPECT_LT(sum / static_cast<double>(rgb.size()), 6.0);  // 4:2:0 loses chroma detail only
}

// Planar YUV of each layout, odd-sized: every pixel takes its luma and the
// chroma sample of its block (2x2 for 4:2:0, 2x1 for 4:2:2, its own for
// 4:4:4, none for mono), compared with the conversion of that one pixel.
// Verifies: REQ-HAL-002
TEST(PixelFormats, EveryPlanarLayoutTakesTheChromaOfItsBlock) {
  const int w = 33;
  const int h = 17;
  struct Layout {
    ChromaLayout layout;
    int shift_x;
    int shift_y;
    bool chroma;
  };
  const Layout layouts[] = {{ChromaLayout::k420, 1, 1, true},
                            {ChromaLayout::k422, 1, 0, true},
                            {ChromaLayout::k444, 0, 0, true},
                            {ChromaLayout::kMono, 0, 0, false}};
  for (const Layout& l : layouts) {
    const auto luma = static_cast<std::size_t>(w * h);
    const int cw = (w + (1 << l.shift_x) - 1) >> l.shift_x;
    const int ch = (h + (1 << l.shift_y) - 1) >> l.shift_y;
    const auto chroma_plane = static_cast<std::size_t>(cw * ch);
    std::vector<std::uint8_t> frame(planar_frame_bytes(w, h, l.layout));
    ASSERT_EQ(frame.size(), luma + (l.chroma ? 2U * chroma_plane : 0U));
    for (std::size_t i = 0; i < luma; ++i) {
      frame[i] = static_cast<std::uint8_t>(16U + (i * 7U) % 220U);
    }
    if (l.chroma) {
      for (std::size_t i = 0; i < chroma_plane; ++i) {
        frame[luma + i] = static_cast<std::uint8_t>(20U + (i * 13U) % 216U);                 // Cb
        frame[luma + chroma_plane + i] = static_cast<std::uint8_t>(236U - (i * 11U) % 216U);  // Cr
      }
    }
    Image out(w, h);
    planar_yuv_to_rgb(frame.data(), w, h, l.layout, YuvRange::kLimited, out.view);
    int wrong = 0;
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const auto c = static_cast<std::size_t>((y >> l.shift_y) * cw + (x >> l.shift_x));
        const std::uint8_t one[3] = {frame[static_cast<std::size_t>(y * w + x)],
                                     l.chroma ? frame[luma + c] : std::uint8_t{128U},
                                     l.chroma ? frame[luma + chroma_plane + c] : std::uint8_t{128U}};
        Image pixel(1, 1);
        planar_yuv_to_rgb(one, 1, 1, ChromaLayout::k444, YuvRange::kLimited, pixel.view);
        const std::uint8_t* got = out.view.row(y) + 3 * x;
        wrong += std::memcmp(got, pixel.bytes.data(), 3U) != 0 ? 1 : 0;
      }
    }
    EXPECT_EQ(wrong, 0) << "layout " << static_cast<int>(l.layout);
  }
}

TEST(PixelFormats, YuyvGreyAndWhite) {
  // Limited range: Y 16 = black, 235 = white, C 128 = no colour.
  const std::uint8_t yuyv[8] = {16, 128, 235, 128, 126, 128, 126, 128};
  Image out(4, 1);
  yuyv_to_rgb(yuyv, 8U, 4, 1, YuvRange::kLimited, out.view);
  EXPECT_EQ(out.bytes[0], 0);
  EXPECT_EQ(out.bytes[3], 255);
  EXPECT_EQ(out.bytes[4], 255);
  EXPECT_NEAR(out.bytes[6], 128, 1);
}

TEST(Y4mSource, WriterAndSourceRoundTripWithoutAllocating) {
  const std::string dir = temp_dir("y4m");
  const std::string path = dir + "/clip.y4m";
  const int w = 64;
  const int h = 48;
  {
    Y4mWriter writer;
    ASSERT_TRUE(writer.open(path.c_str(), w, h, 25, 1).ok());
    for (int i = 0; i < 3; ++i) {
      const auto rgb = testing::make_pattern(w, h, i);
      ASSERT_TRUE(writer.write(ImageView{rgb.data(), w, h, static_cast<std::size_t>(w) * 3U}).ok());
    }
    ASSERT_TRUE(writer.close().ok());
  }
  ReplayOptions options;
  options.loop = true;
  auto source = Y4mSource::open(path.c_str(), options);
  ASSERT_TRUE(source.ok());
  EXPECT_EQ(source.value()->width(), w);
  EXPECT_DOUBLE_EQ(source.value()->rate_hz(), 25.0);
  EXPECT_EQ(source.value()->header().range, YuvRange::kFull);
  Image out(w, h);
  FrameInfo info;
  test::AllocationScope scope;
  for (int i = 0; i < 10; ++i) {  // loops over the three frames
    ASSERT_TRUE(source.value()->acquire(out.view, info).ok());
    EXPECT_EQ(info.sequence, static_cast<std::uint32_t>(i));
  }
  EXPECT_EQ(scope.count(), 0U);
}

// Verifies: REQ-HAL-002
TEST(Y4mSource, EndOfStreamTruncationAndWrongSize) {
  const std::string dir = temp_dir("y4m2");
  const std::string path = dir + "/clip.y4m";
  const int w = 16;
  const int h = 8;
  {
    Y4mWriter writer;
    ASSERT_TRUE(writer.open(path.c_str(), w, h, 25, 1).ok());
    const auto rgb = testing::make_pattern(w, h, 0);
    ASSERT_TRUE(writer.write(ImageView{rgb.data(), w, h, static_cast<std::size_t>(w) * 3U}).ok());
    ASSERT_TRUE(writer.write(ImageView{rgb.data(), w, h, static_cast<std::size_t>(w) * 3U}).ok());
    ASSERT_TRUE(writer.close().ok());
  }
  // Cut the second frame in half.
  std::ifstream in(path, std::ios::binary);
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  bytes.resize(bytes.size() - 50U);
  write_bytes(path, bytes);
  auto source = Y4mSource::open(path.c_str(), ReplayOptions{});
  ASSERT_TRUE(source.ok());
  Image out(w, h);
  FrameInfo info;
  EXPECT_TRUE(source.value()->acquire(out.view, info).ok());
  EXPECT_EQ(source.value()->acquire(out.view, info).error(), CameraError::kTruncated);
  EXPECT_EQ(source.value()->acquire(out.view, info).error(), CameraError::kEndOfStream);
  Image wrong(w + 2, h);
  EXPECT_EQ(source.value()->acquire(wrong.view, info).error(), CameraError::kWrongSize);
  ReplayOptions sized;
  sized.width = 32;
  sized.height = 8;
  EXPECT_EQ(Y4mSource::open(path.c_str(), sized).error(), CameraError::kWrongSize);
  EXPECT_EQ(Y4mSource::open((dir + "/none.y4m").c_str(), ReplayOptions{}).error(), CameraError::kNotFound);
  write_bytes(dir + "/bad.y4m", std::vector<std::uint8_t>{'J', 'U', 'N', 'K', '\n'});
  EXPECT_EQ(Y4mSource::open((dir + "/bad.y4m").c_str(), ReplayOptions{}).error(), CameraError::kCorrupt);
}

// A 4:2:2 clip written by hand, as `ffmpeg -pix_fmt yuv422p` does, with
// per-frame parameters after FRAME (the format allows them): read and
// converted like the planar frame itself; a file that ends inside a FRAME
// line is truncated.
// Verifies: REQ-HAL-002
TEST(Y4mSource, A422ClipWithFrameParameters) {
  const std::string dir = temp_dir("y4m422");
  const int w = 6;
  const int h = 4;
  const std::size_t bytes = planar_frame_bytes(w, h, ChromaLayout::k422);
  std::vector<std::uint8_t> planes(bytes);
  for (std::size_t i = 0; i < bytes; ++i) {
    planes[i] = static_cast<std::uint8_t>(30U + i * 5U);
  }
  const std::string header = "YUV4MPEG2 W6 H4 F25:1 Ip C422\n";
  std::vector<std::uint8_t> file(header.begin(), header.end());
  const std::string frame_line = "FRAME Ixyz\n";
  for (int f = 0; f < 2; ++f) {
    file.insert(file.end(), frame_line.begin(), frame_line.end());
    file.insert(file.end(), planes.begin(), planes.end());
  }
  const std::string cut = "FRAME Ix";  // ends inside the line
  file.insert(file.end(), cut.begin(), cut.end());
  write_bytes(dir + "/clip.y4m", file);
  auto source = Y4mSource::open((dir + "/clip.y4m").c_str(), ReplayOptions{});
  ASSERT_TRUE(source.ok());
  Image expected(w, h);
  planar_yuv_to_rgb(planes.data(), w, h, ChromaLayout::k422, YuvRange::kLimited, expected.view);
  Image out(w, h);
  FrameInfo info;
  for (int f = 0; f < 2; ++f) {
    ASSERT_TRUE(source.value()->acquire(out.view, info).ok()) << f;
    EXPECT_EQ(out.bytes, expected.bytes) << f;
  }
  EXPECT_EQ(source.value()->acquire(out.view, info).error(), CameraError::kTruncated);
}

// Only 8-bit colour is taken; every other colour space is refused with its
// tag named (C420p10 used to be read as 8-bit 4:2:0: wrong frame size, garbage).
// Verifies: REQ-HAL-002
TEST(Y4mHeader, RefusesHighBitDepthMonoAndUnknownColourSpacesNamingTheTag) {
  const char* refused[] = {"C420p10", "C420p12", "C420p16", "C444p10", "C422p10", "Cmono", "Cmono16",
                           "C444alpha", "C411", "C420jpegx", "C"};
  for (const char* tag : refused) {
    const std::string line = std::string("YUV4MPEG2 W64 H48 F25:1 ") + tag;
    char detail[192] = {};
    const auto h = parse_y4m_header(line.c_str(), line.size(), detail, sizeof detail);
    ASSERT_FALSE(h.ok()) << tag;
    EXPECT_EQ(h.error(), CameraError::kUnsupported) << tag;
    EXPECT_NE(std::strstr(detail, (std::string("'") + tag + "'").c_str()), nullptr) << tag << ": " << detail;
  }
  const struct {
    const char* tag;
    ChromaLayout layout;
  } taken[] = {{"C420", ChromaLayout::k420},      {"C420jpeg", ChromaLayout::k420}, {"C420mpeg2", ChromaLayout::k420},
               {"C420paldv", ChromaLayout::k420}, {"C422", ChromaLayout::k422},     {"C444", ChromaLayout::k444}};
  for (const auto& t : taken) {
    const std::string line = std::string("YUV4MPEG2 W64 H48 F25:1 ") + t.tag;
    const auto h = parse_y4m_header(line.c_str(), line.size());
    ASSERT_TRUE(h.ok()) << t.tag;
    EXPECT_EQ(h.value().layout, t.layout) << t.tag;
  }
}

// A 16x8 4:2:0 clip of `frames` frames, as bytes: the header, then each
// "FRAME\n" and its planes (frame i's bytes all 40 + i).
std::vector<std::uint8_t> y4m_clip(int frames, std::size_t& header_bytes, std::size_t& frame_bytes) {
  const std::string header = "YUV4MPEG2 W16 H8 F25:1 Ip C420jpeg\n";
  frame_bytes = planar_frame_bytes(16, 8, ChromaLayout::k420);
  header_bytes = header.size();
  std::vector<std::uint8_t> file(header.begin(), header.end());
  for (int f = 0; f < frames; ++f) {
    const std::string tag = "FRAME\n";
    file.insert(file.end(), tag.begin(), tag.end());
    file.insert(file.end(), frame_bytes, static_cast<std::uint8_t>(40 + f));
  }
  return file;
}

// A damaged frame tag ("FRAMX") used to consume 6 bytes per try: tens of
// thousands of dropped frames from one bad byte. Now the frame is dropped
// once and the stream resynchronises on the next FRAME tag.
// Verifies: REQ-HAL-002
TEST(Y4mSource, ADamagedFrameTagDropsOneFrameAndResynchronises) {
  const std::string dir = temp_dir("y4mframx");
  std::size_t header_bytes = 0U;
  std::size_t frame_bytes = 0U;
  std::vector<std::uint8_t> file = y4m_clip(3, header_bytes, frame_bytes);
  file[header_bytes + 4U] = 'X';  // FRAME -> FRAMX, the first frame's tag
  write_bytes(dir + "/clip.y4m", file);
  auto source = Y4mSource::open((dir + "/clip.y4m").c_str(), ReplayOptions{});
  ASSERT_TRUE(source.ok());
  Image out(16, 8);
  FrameInfo info;
  {
    test::AllocationScope scope;
    EXPECT_EQ(source.value()->acquire(out.view, info).error(), CameraError::kCorrupt);
    EXPECT_EQ(scope.count(), 0U);
  }
  EXPECT_EQ(source.value()->stop_reason(), nullptr);
  Image expected(16, 8);
  for (int f = 1; f < 3; ++f) {
    ASSERT_TRUE(source.value()->acquire(out.view, info).ok()) << f;
    std::vector<std::uint8_t> planes(frame_bytes, static_cast<std::uint8_t>(40 + f));
    planar_yuv_to_rgb(planes.data(), 16, 8, ChromaLayout::k420, YuvRange::kLimited, expected.view);
    EXPECT_EQ(out.bytes, expected.bytes) << f;
  }
  EXPECT_EQ(source.value()->acquire(out.view, info).error(), CameraError::kEndOfStream);
}

// A frame one byte short: its read takes the next tag's first byte, the next
// tag is then misread, and the stream finds the tag that follows.
// Verifies: REQ-HAL-002
TEST(Y4mSource, AShortFrameDropsTheNextFrameNotTheRestOfTheStream) {
  const std::string dir = temp_dir("y4mshort");
  std::size_t header_bytes = 0U;
  std::size_t frame_bytes = 0U;
  std::vector<std::uint8_t> file = y4m_clip(4, header_bytes, frame_bytes);
  file.erase(file.begin() + static_cast<std::ptrdiff_t>(header_bytes + 6U));  // frame 0 one byte short
  write_bytes(dir + "/clip.y4m", file);
  auto source = Y4mSource::open((dir + "/clip.y4m").c_str(), ReplayOptions{});
  ASSERT_TRUE(source.ok());
  Image out(16, 8);
  FrameInfo info;
  int good = 0;
  int dropped = 0;
  for (int i = 0; i < 10; ++i) {
    const auto got = source.value()->acquire(out.view, info);
    if (!got.ok() && got.error() == CameraError::kEndOfStream) {
      break;
    }
    (got.ok() ? good : dropped) += 1;
  }
  EXPECT_EQ(good, 3);  // frame 0 (misread, its planes are all alike), frames 2 and 3
  EXPECT_EQ(dropped, 1);
  EXPECT_EQ(source.value()->stop_reason(), nullptr);
}

// A valid header and then junk: one dropped frame, then the source stops
// (end of stream, also when looping) and says why; it used to drop a frame
// per 6 bytes of junk. The search is bounded: a FRAME tag further than
// kY4mResyncFrames frame sizes away is not looked for.
// Verifies: REQ-HAL-002
TEST(Y4mSource, JunkAfterTheHeaderStopsTheSourceWithAReason) {
  const std::string dir = temp_dir("y4mjunk");
  std::size_t header_bytes = 0U;
  std::size_t frame_bytes = 0U;
  std::vector<std::uint8_t> file = y4m_clip(0, header_bytes, frame_bytes);
  for (std::size_t i = 0; i < (kY4mResyncFrames + 1U) * (frame_bytes + 1024U); ++i) {
    file.push_back(static_cast<std::uint8_t>('A' + i % 7U));
  }
  const std::vector<std::uint8_t> one_frame = y4m_clip(1, header_bytes, frame_bytes);
  file.insert(file.end(), one_frame.begin() + static_cast<std::ptrdiff_t>(header_bytes), one_frame.end());
  write_bytes(dir + "/junk.y4m", file);
  ReplayOptions options;
  options.loop = true;
  auto source = Y4mSource::open((dir + "/junk.y4m").c_str(), options);
  ASSERT_TRUE(source.ok());
  Image out(16, 8);
  FrameInfo info;
  EXPECT_EQ(source.value()->acquire(out.view, info).error(), CameraError::kCorrupt);
  ASSERT_NE(source.value()->stop_reason(), nullptr);
  EXPECT_NE(std::strstr(source.value()->stop_reason(), "no FRAME tag"), nullptr) << source.value()->stop_reason();
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(source.value()->acquire(out.view, info).error(), CameraError::kEndOfStream);
  }
  // Starting again (the loop's retry) clears the stop; the junk stops it again.
  ASSERT_TRUE(source.value()->reopen().ok());
  EXPECT_EQ(source.value()->stop_reason(), nullptr);
  EXPECT_EQ(source.value()->acquire(out.view, info).error(), CameraError::kCorrupt);
  EXPECT_NE(source.value()->stop_reason(), nullptr);
}

// Verifies: REQ-HAL-002
TEST(Y4mSource, AHeaderOnlyFileIsAnEmptySourceSaidSo) {
  const std::string dir = temp_dir("y4mempty");
  std::size_t header_bytes = 0U;
  std::size_t frame_bytes = 0U;
  write_bytes(dir + "/empty.y4m", y4m_clip(0, header_bytes, frame_bytes));
  char detail[192] = {};
  const auto opened = Y4mSource::open((dir + "/empty.y4m").c_str(), ReplayOptions{}, detail, sizeof detail);
  ASSERT_FALSE(opened.ok());
  EXPECT_EQ(opened.error(), CameraError::kEndOfStream);
  EXPECT_NE(std::strstr(detail, "no frame"), nullptr) << detail;
  write_bytes(dir + "/p10.y4m", std::vector<std::uint8_t>{'Y', 'U', 'V', '4', 'M', 'P', 'E', 'G', '2', ' ', 'W', '2', ' ',
                                                          'H', '2', ' ', 'C', '4', '2', '0', 'p', '1', '0', '\n'});
  const auto p10 = Y4mSource::open((dir + "/p10.y4m").c_str(), ReplayOptions{}, detail, sizeof detail);
  ASSERT_FALSE(p10.ok());
  EXPECT_EQ(p10.error(), CameraError::kUnsupported);
  EXPECT_NE(std::strstr(detail, "'C420p10'"), nullptr) << detail;
}

// Found by fuzz_y4m (docs/fuzzing.md): a 44-byte file whose header claims a
// 16384 x 16384 4:4:4 frame made open() allocate and pre-fault 805 MB before
// the first read found the frame truncated. A file too short for one frame
// is refused at open, saying so.
TEST(Y4mSource, AFileTooShortForOneFrameIsRefusedBeforeItsBuffer) {
  const std::string dir = temp_dir("y4mshort");
  const std::string text = "YUV4MPEG2 W16384 H16384 F25:1 C444\nFRAME\nabc";
  write_bytes(dir + "/short.y4m", std::vector<std::uint8_t>(text.begin(), text.end()));
  char detail[192] = {};
  const auto opened = Y4mSource::open((dir + "/short.y4m").c_str(), ReplayOptions{}, detail, sizeof detail);
  ASSERT_FALSE(opened.ok());
  EXPECT_EQ(opened.error(), CameraError::kTruncated);
  EXPECT_NE(std::strstr(detail, "16384x16384"), nullptr) << detail;
  // One byte short of a whole small frame: refused too; the whole frame opens.
  const std::string header = "YUV4MPEG2 W4 H2 C420\nFRAME\n";
  std::vector<std::uint8_t> clip(header.begin(), header.end());
  clip.resize(clip.size() + planar_frame_bytes(4, 2, ChromaLayout::k420) - 1U, 128U);
  write_bytes(dir + "/cut.y4m", clip);
  EXPECT_EQ(Y4mSource::open((dir + "/cut.y4m").c_str(), ReplayOptions{}).error(), CameraError::kTruncated);
  clip.push_back(128U);
  write_bytes(dir + "/whole.y4m", clip);
  EXPECT_TRUE(Y4mSource::open((dir + "/whole.y4m").c_str(), ReplayOptions{}).ok());
}

// Verifies: REQ-HAL-002
TEST(JpegFileSource, DirectorySortedWithACorruptFileDropped) {
  const std::string dir = temp_dir("jpg");
  const int w = 40;
  const int h = 30;
  write_bytes(dir + "/frame_002.jpg", testing::encode_jpeg(testing::make_pattern(w, h, 2), w, h));
  write_bytes(dir + "/frame_000.jpg", testing::encode_jpeg(testing::make_pattern(w, h, 0), w, h));
  auto broken = testing::encode_jpeg(testing::make_pattern(w, h, 1), w, h);
  broken.resize(broken.size() / 3U);
  write_bytes(dir + "/frame_001.jpg", broken);
  write_bytes(dir + "/notes.txt", std::vector<std::uint8_t>{'x'});
  auto source = JpegFileSource::open(dir.c_str(), ReplayOptions{});
  ASSERT_TRUE(source.ok());
  ASSERT_EQ(source.value()->file_count(), 3U);
  EXPECT_EQ(source.value()->width(), w);
  EXPECT_NE(std::string(source.value()->file_name(0)).find("frame_000"), std::string::npos);
  Image out(w, h);
  FrameInfo info;
  EXPECT_TRUE(source.value()->acquire(out.view, info).ok());
  const auto second = source.value()->acquire(out.view, info);
  ASSERT_FALSE(second.ok());
  EXPECT_EQ(second.error(), CameraError::kTruncated);
  EXPECT_TRUE(source.value()->acquire(out.view, info).ok());
  EXPECT_EQ(source.value()->acquire(out.view, info).error(), CameraError::kEndOfStream);
}

// max_files keeps the first names in order, whatever order the file system
// lists them in (here the reverse of their names' order, on most file
// systems: created last to first).
// Verifies: REQ-HAL-002
TEST(JpegFileSource, DirectoryBeyondMaxFilesKeepsTheFirstNames) {
  const std::string dir = temp_dir("jpgmax");
  const int w = 16;
  const int h = 8;
  for (int i = 5; i >= 0; --i) {
    char name[32];
    static_cast<void>(std::snprintf(name, sizeof name, "/f%d.jpg", i));
    write_bytes(dir + name, testing::encode_jpeg(testing::make_pattern(w, h, i), w, h));
  }
  ReplayOptions options;
  options.max_files = 2U;
  auto source = JpegFileSource::open(dir.c_str(), options);
  ASSERT_TRUE(source.ok());
  ASSERT_EQ(source.value()->file_count(), 2U);
  EXPECT_NE(std::string(source.value()->file_name(0)).find("/f0.jpg"), std::string::npos);
  EXPECT_NE(std::string(source.value()->file_name(1)).find("/f1.jpg"), std::string::npos);
}

// Verifies: REQ-HAL-002
TEST(JpegFileSource, ListFileWithRelativePaths) {
  const std::string dir = temp_dir("jpglist");
  const int w = 24;
  const int h = 16;
  write_bytes(dir + "/a.jpg", testing::encode_jpeg(testing::make_pattern(w, h, 0), w, h));
  write_bytes(dir + "/b.jpg", testing::encode_jpeg(testing::make_pattern(48, 16, 0), 48, 16));
  {
    std::ofstream list(dir + "/list.txt");
    list << "# frames\nb.jpg\n" << dir << "/a.jpg\n\n";
  }
  ReplayOptions options;
  options.width = w;
  options.height = h;
  auto source = JpegFileSource::open((dir + "/list.txt").c_str(), options);
  ASSERT_TRUE(source.ok());
  ASSERT_EQ(source.value()->file_count(), 2U);
  Image out(w, h);
  FrameInfo info;
  EXPECT_EQ(source.value()->acquire(out.view, info).error(), CameraError::kWrongSize);
  EXPECT_TRUE(source.value()->acquire(out.view, info).ok());
  EXPECT_EQ(JpegFileSource::open((dir + "/missing").c_str(), options).error(), CameraError::kNotFound);
}

// The replay sources' opening (a directory, a list file, a Y4M clip), with
// memory running out at each of its allocations in turn (the C library's
// directory and file handles included): an error, everything taken before
// freed.
// Verifies: REQ-ERR-007
TEST(FileSources, OpeningReportsOutOfMemoryAtAnyOfItsAllocations) {
  if (!test::malloc_hook_active()) {
    GTEST_SKIP() << "malloc belongs to the sanitizer's runtime in this build";
  }
  const std::string dir = temp_dir("oom");
  const int w = 24;
  const int h = 16;
  write_bytes(dir + "/a.jpg", testing::encode_jpeg(testing::make_pattern(w, h, 0), w, h));
  write_bytes(dir + "/b.jpg", testing::encode_jpeg(testing::make_pattern(w, h, 1), w, h));
  {
    std::ofstream list(dir + "/list.txt");
    list << "b.jpg\na.jpg\n";
  }
  {
    Y4mWriter writer;
    ASSERT_TRUE(writer.open((dir + "/clip.y4m").c_str(), w, h, 25, 1).ok());
    const auto rgb = testing::make_pattern(w, h, 2);
    ASSERT_TRUE(writer.write(ImageView{rgb.data(), w, h, static_cast<std::size_t>(w) * 3U}).ok());
    ASSERT_TRUE(writer.close().ok());
  }
  const std::string jpeg_dir = dir;
  const std::string jpeg_list = dir + "/list.txt";
  const std::string clip = dir + "/clip.y4m";
  CameraError error = CameraError::kNone;
  const auto check = [&](const char* what) {
    return [&error, what](const test::OutOfMemoryOutcome& o) {
      ASSERT_FALSE(o.succeeded) << what << ", allocation " << o.nth;
      EXPECT_EQ(error, CameraError::kOutOfMemory) << what << ", allocation " << o.nth << ": " << to_string(error);
      EXPECT_EQ(o.leaked, 0U) << what << ", out of memory at allocation " << o.nth;
    };
  };
  const auto open_jpeg = [&](const std::string& path) {
    return [&error, path]() {
      const auto source = JpegFileSource::open(path.c_str(), ReplayOptions{});
      error = source.ok() ? CameraError::kNone : source.error();
      return source.ok();  // the source is released here: only the count matters
    };
  };
  EXPECT_GE(test::run_out_of_memory_at_each_allocation(open_jpeg(jpeg_dir), check("directory")), 3U);
  EXPECT_GE(test::run_out_of_memory_at_each_allocation(open_jpeg(jpeg_list), check("list")), 3U);
  const auto open_clip = [&]() {
    const auto source = Y4mSource::open(clip.c_str(), ReplayOptions{});
    error = source.ok() ? CameraError::kNone : source.error();
    return source.ok();
  };
  EXPECT_GE(test::run_out_of_memory_at_each_allocation(open_clip, check("clip")), 2U);
}

class StripesRenderer final : public SceneRenderer {
 public:
  int width() const noexcept override { return 8; }
  int height() const noexcept override { return 4; }
  std::uint32_t frame_count() const noexcept override { return 2U; }
  Status<CameraError> render(std::uint32_t index, const MutableImageView& out, FrameTruth& truth) noexcept override {
    for (int y = 0; y < out.height; ++y) {
      for (int x = 0; x < out.width * 3; ++x) {
        out.row(y)[x] = static_cast<std::uint8_t>(index * 10U);
      }
    }
    truth.valid = true;
    truth.tcp_mm = {1.0, 2.0, static_cast<double>(index)};
    return ok_status<CameraError>();
  }
};

// The truth travels beside the frame (TruthSource), not in FrameInfo.
TEST(SimCamera, KeepsTheTruthBesideTheFrameAndLoops) {
  StripesRenderer renderer;
  SimCamera camera(renderer, 25.0, true);
  Image out(8, 4);
  FrameInfo info;
  for (std::uint32_t i = 0; i < 5U; ++i) {
    ASSERT_TRUE(camera.acquire(out.view, info).ok());
    EXPECT_TRUE(camera.last_truth().valid);
    EXPECT_DOUBLE_EQ(camera.last_truth().tcp_mm[2], static_cast<double>(i % 2U));
    EXPECT_EQ(info.sequence, i);
  }
  SimCamera once(renderer, 25.0, false);
  ASSERT_TRUE(once.acquire(out.view, info).ok());
  ASSERT_TRUE(once.acquire(out.view, info).ok());
  EXPECT_EQ(once.acquire(out.view, info).error(), CameraError::kEndOfStream);
  Image wrong(4, 4);
  EXPECT_EQ(camera.acquire(wrong.view, info).error(), CameraError::kWrongSize);
}

// Verifies: REQ-HAL-002
TEST(V4l2Source, MissingDeviceAndNonVideoDeviceAreErrors) {
  V4l2Options options;
  EXPECT_EQ(V4l2Source::open("/dev/video-does-not-exist", options).error(), CameraError::kNotFound);
  EXPECT_EQ(V4l2Source::open("/dev/null", options).error(), CameraError::kUnsupported);
  options.buffers = 1;
  EXPECT_EQ(V4l2Source::open("/dev/null", options).error(), CameraError::kBadArgument);
  V4l2PixelFormat format{};
  EXPECT_TRUE(parse_v4l2_pixel_format("mjpeg", format));
  EXPECT_EQ(format, V4l2PixelFormat::kMjpeg);
  EXPECT_FALSE(parse_v4l2_pixel_format("nv12", format));
}

}  // namespace
}  // namespace hal
}  // namespace tcpest
