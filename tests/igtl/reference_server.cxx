// An OpenIGTLink server written with the protocol's reference implementation
// (Debian's libopenigtlink-dev): five frames, each an 8-bit IMAGE from `Image`
// and TRANSFORMs from `ProbeToTracker` and `ReferenceToTracker` stamped with the
// frame's time, a STATUS, then a STRING from `SequenceEnd`. The pixels and
// poses follow formulas the test recomputes. The messages are packed by the
// library and sent on a plain socket bound to loopback only.
//
//     reference_server PORT
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "igtlImageMessage.h"
#include "igtlOSUtil.h"
#include "igtlStatusMessage.h"
#include "igtlStringMessage.h"
#include "igtlTransformMessage.h"

static void send(int socket, igtl::MessageBase::Pointer m) {
  m->Pack();
  const char* p = static_cast<const char*>(m->GetPackPointer());
  size_t left = m->GetPackSize();
  while (left > 0) {
    ssize_t n = ::send(socket, p, left, 0);
    if (n <= 0) std::exit(4);
    p += n;
    left -= static_cast<size_t>(n);
  }
}

int main(int argc, char** argv) {
  if (argc != 2) return 2;
  int listener = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<uint16_t>(std::atoi(argv[1])));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (bind(listener, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0 || listen(listener, 1) != 0) return 1;
  std::printf("listening\n");
  std::fflush(stdout);
  int socket = accept(listener, nullptr, nullptr);
  if (socket < 0) return 3;
  for (int f = 0; f < 5; f++) {
    igtl::TimeStamp::Pointer ts = igtl::TimeStamp::New();
    ts->SetTime(1000.0 + 0.125 * f);
    igtl::ImageMessage::Pointer image = igtl::ImageMessage::New();
    int size[3] = {64, 48, 1};
    int offset[3] = {0, 0, 0};
    float spacing[3] = {0.2f, 0.3f, 1.0f};
    image->SetDimensions(size);
    image->SetSpacing(spacing);
    image->SetScalarTypeToUint8();
    image->SetDeviceName("Image");
    image->SetSubVolume(size, offset);
    image->AllocateScalars();
    unsigned char* p = static_cast<unsigned char*>(image->GetScalarPointer());
    for (int i = 0; i < 64 * 48; i++) p[i] = static_cast<unsigned char>((i * 7 + f) % 256);
    image->SetTimeStamp(ts);
    send(socket, image.GetPointer());
    const char* names[2] = {"ProbeToTracker", "ReferenceToTracker"};
    for (int n = 0; n < 2; n++) {
      igtl::Matrix4x4 m;
      igtl::IdentityMatrix(m);
      double a = 0.1 * f + n;
      m[0][0] = std::cos(a); m[0][1] = -std::sin(a);
      m[1][0] = std::sin(a); m[1][1] = std::cos(a);
      m[0][3] = 10.0f + f; m[1][3] = 20.0f * n; m[2][3] = -30.5f;
      igtl::TransformMessage::Pointer t = igtl::TransformMessage::New();
      t->SetDeviceName(names[n]);
      t->SetMatrix(m);
      t->SetTimeStamp(ts);
      send(socket, t.GetPointer());
    }
  }
  igtl::StatusMessage::Pointer status = igtl::StatusMessage::New();
  status->SetDeviceName("Tracker");
  status->SetCode(igtl::StatusMessage::STATUS_OK);
  status->SetErrorName("none");
  status->SetStatusString("tracking");
  send(socket, status.GetPointer());
  igtl::StringMessage::Pointer end = igtl::StringMessage::New();
  end->SetDeviceName("SequenceEnd");
  end->SetString("end");
  send(socket, end.GetPointer());
  igtl::Sleep(2000);
  close(socket);
  close(listener);
  return 0;
}
