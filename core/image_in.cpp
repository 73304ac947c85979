#include "image_in.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>

#include "error.h"
#include "image_codec.h"
#include "provenance.h"

namespace eco {

namespace {

/// Points file descriptor 2 at /dev/null for its lifetime: libpng's default error handler
/// prints "libpng error: ..." there before OpenImageIO hands the same reason to us, which
/// left stray lines around eco's one-line error (issue 26). Images are read on the main
/// thread before any parallel work, so nothing else is silenced.
class QuietStderr {
public:
    QuietStderr() {
        std::fflush(stderr);
        saved_ = ::dup(2);
        const int devNull = ::open("/dev/null", O_WRONLY | O_CLOEXEC);
        if (saved_ >= 0 && devNull >= 0) ::dup2(devNull, 2);
        if (devNull >= 0) ::close(devNull);
    }
    QuietStderr(const QuietStderr&) = delete;
    QuietStderr& operator=(const QuietStderr&) = delete;
    ~QuietStderr() {
        std::fflush(stderr);
        if (saved_ >= 0) {
            ::dup2(saved_, 2);
            ::close(saved_);
        }
    }

private:
    int saved_ = -1;
};

/// OpenImageIO's reasons come as several lines ("Read error: hit end of file\nPNG read
/// error: ...\nPNG library error"): one line, repeated lines dropped.
std::string oneLine(const std::string& text) {
    std::vector<std::string> parts;
    std::size_t start = 0;
    while (start <= text.size()) {
        std::size_t end = text.find('\n', start);
        if (end == std::string::npos) end = text.size();
        std::string part = text.substr(start, end - start);
        while (!part.empty() && (part.back() == '\r' || part.back() == ' ')) part.pop_back();
        if (!part.empty() && std::find(parts.begin(), parts.end(), part) == parts.end()) parts.push_back(part);
        start = end + 1;
    }
    std::string out;
    for (const auto& p : parts) out += (out.empty() ? "" : "; ") + p;
    return out;
}

}  // namespace

ImagePixels readImagePixels(const std::string& path, const std::string& what, int maxChannels,
                            const std::function<void(int, int, int)>& checkHeader) {
    if (std::FILE* f = std::fopen(path.c_str(), "rb")) std::fclose(f);
    else throw IoError(path + ": cannot open " + what + " (missing or unreadable)");
    noteInputFile(path);  // recorded in /provenance with its hash
    ImagePixels px;
    std::string failure;
    {
        QuietStderr quiet;
        std::string openError;
        auto in = openImageFile(path, openError);
        if (!in) {
            const std::string why = oneLine(openError);
            failure = "cannot read " + what + ": " + (why.empty() ? std::string("unrecognised or corrupt image") : why);
        } else {
            px.width = in->width();
            px.height = in->height();
            px.channels = maxChannels > 0 ? std::min(maxChannels, in->channels()) : in->channels();
            px.stored = in->stored();
            if (px.width <= 0 || px.height <= 0 || px.channels < 1) {
                failure = what + " has no pixels";
            } else {
                if (checkHeader) checkHeader(px.width, px.height, px.channels);  // may throw; stderr is restored
                px.values.resize(static_cast<std::size_t>(px.width) * static_cast<std::size_t>(px.height) *
                                 static_cast<std::size_t>(px.channels));
                // A truncated file's error recorded on the way counts too (readFloat).
                if (!in->readFloat(px.channels, px.values.data())) {
                    const std::string why = oneLine(in->error());
                    failure = "cannot read " + what + " pixels (corrupt or truncated file?)" + (why.empty() ? "" : ": " + why);
                }
            }
        }
    }
    if (!failure.empty()) throw IoError(path + ": " + failure);
    return px;
}

}  // namespace eco
