#include "machine.hpp"

#include <ctime>
#include <fstream>
#include <string>
#include <thread>

#include "builders.hpp"

namespace dynbvh::study {

namespace {
std::string trim(std::string s) {
    while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\n')) s.pop_back();
    std::size_t i = 0;
    while (i < s.size() && (s[i] == ' ' || s[i] == '\t')) ++i;
    return s.substr(i);
}
} // namespace

MachineInfo machine_info() {
    MachineInfo m;
    {
        std::ifstream in("/proc/cpuinfo");
        std::string line;
        while (std::getline(in, line)) {
            if (line.rfind("model name", 0) == 0) {
                const auto colon = line.find(':');
                if (colon != std::string::npos) m.cpu = trim(line.substr(colon + 1));
                break;
            }
        }
        if (m.cpu.empty()) m.cpu = "unknown";
    }
    m.cores = std::thread::hardware_concurrency();
    {
        std::ifstream in("/proc/meminfo");
        std::string key;
        double kb = 0;
        while (in >> key >> kb) {
            if (key == "MemTotal:") {
                m.memory_gib = kb / (1024.0 * 1024.0);
                break;
            }
            in.ignore(1 << 10, '\n');
        }
    }
#if defined(__clang__)
    m.compiler = std::string("clang ") + __clang_version__;
#elif defined(__GNUC__)
    m.compiler = std::string("g++ ") + __VERSION__;
#else
    m.compiler = "unknown";
#endif
    const std::time_t now = std::time(nullptr);
    std::tm tm{};
    gmtime_r(&now, &tm);
    char buf[64];
    std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
    m.date = buf;
    m.embree = embree_version();
    return m;
}

} // namespace dynbvh::study
