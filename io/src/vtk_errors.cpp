#include "octshape/io/vtk_errors.h"

#include <vtkAlgorithm.h>
#include <vtkCommand.h>
#include <vtkExecutive.h>
#include <vtkLogger.h>
#include <vtkNew.h>
#include <vtkObject.h>
#include <vtkOutputWindow.h>

#include <cctype>
#include <iostream>
#include <mutex>
#include <utility>
#include <vector>

namespace octshape::io {
namespace {

// `m` without its " (0xADDR)" parts (the space before one optional). By hand, not std::regex:
// GCC 12 warns (-Wmaybe-uninitialized) inside <regex> at -O1 under the sanitizers.
std::string without_addresses(const std::string& m) {
    std::string out;
    std::size_t i = 0;
    while (i < m.size()) {
        const std::size_t start = m[i] == ' ' && i + 1 < m.size() && m[i + 1] == '(' ? i + 1 : i;
        if (m.compare(start, 3, "(0x") == 0) {
            std::size_t j = start + 3;
            while (j < m.size() && std::isxdigit(static_cast<unsigned char>(m[j])) != 0) ++j;
            if (j > start + 3 && j < m.size() && m[j] == ')') {
                i = j + 1;
                continue;
            }
        }
        out += m[i];
        ++i;
    }
    return out;
}

// VTK's message: "ERROR: In FILE, line N\nClass (0xADDR): text\n\n" (warnings alike). Keeps
// "Class: text", its first line, without addresses: they mean nothing to a user.
std::string one_line(const char* raw) {
    if (raw == nullptr) return "unknown VTK error";
    std::string m(raw);
    if (m.starts_with("ERROR: In ") || m.starts_with("Warning: In ")) {
        const auto nl = m.find('\n');
        m = nl == std::string::npos ? std::string() : m.substr(nl + 1);
    }
    m = m.substr(0, m.find('\n'));
    m = without_addresses(m);
    return m.empty() ? "unknown VTK error" : m;
}

class FirstReport : public vtkCommand {
public:
    static FirstReport* New() { return new FirstReport; }
    void Execute(vtkObject* /*caller*/, unsigned long /*event*/, void* data) override {
        if (message.empty()) message = one_line(static_cast<const char*>(data));
    }
    std::string message;
    bool warnings = false;
};

// The report of an object nobody observes (a reader's XML parser, a filter's helper) goes to
// VTK's output window (and its logger, which this window replaces on stderr): while
// vtk_first_error runs on this thread it is collected, otherwise printed as VTK would.
thread_local FirstReport* t_collector = nullptr;

class CollectingWindow : public vtkOutputWindow {
public:
    static CollectingWindow* New() { return new CollectingWindow; }
    void DisplayErrorText(const char* text) override {
        if (t_collector != nullptr) {
            t_collector->Execute(nullptr, vtkCommand::ErrorEvent, const_cast<char*>(text));
        } else {
            std::cerr << text;
        }
    }
    void DisplayWarningText(const char* text) override {
        if (t_collector != nullptr && t_collector->warnings) {
            t_collector->Execute(nullptr, vtkCommand::WarningEvent, const_cast<char*>(text));
        } else {
            std::cerr << text;
        }
    }
};

}  // namespace

std::string vtk_first_error(vtkObject* object, const std::function<void()>& run,
                            VtkReport report) {
    static std::once_flag installed;
    std::call_once(installed, [] {
        vtkNew<CollectingWindow> window;
        vtkOutputWindow::SetInstance(window);
        vtkLogger::SetStderrVerbosity(vtkLogger::VERBOSITY_OFF);
    });
    vtkNew<FirstReport> first;
    first->warnings = report == VtkReport::kErrorsAndWarnings;
    std::vector<std::pair<vtkObject*, unsigned long>> tags;
    const auto watch = [&](vtkObject* o) {
        if (o == nullptr) return;
        tags.emplace_back(o, o->AddObserver(vtkCommand::ErrorEvent, first));
        if (report == VtkReport::kErrorsAndWarnings) {
            tags.emplace_back(o, o->AddObserver(vtkCommand::WarningEvent, first));
        }
    };
    watch(object);
    if (auto* algorithm = vtkAlgorithm::SafeDownCast(object)) watch(algorithm->GetExecutive());
    struct Unwatch {
        std::vector<std::pair<vtkObject*, unsigned long>>& tags;
        FirstReport* outer;
        ~Unwatch() {
            for (const auto& [o, tag] : tags) o->RemoveObserver(tag);
            t_collector = outer;
        }
    } unwatch{tags, t_collector};
    t_collector = first;
    run();
    return first->message;
}

}  // namespace octshape::io
